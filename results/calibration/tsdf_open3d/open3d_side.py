"""Open3D's side of the TSDF check: fuse the same depth images with Open3D's ``UniformTSDFVolume`` (what VGN and
GIGA use), time it, and compare the network input voxel by voxel with ours. Run in a venv holding open3d."""

import time

import numpy as np
import open3d as o3d

data = np.load("/tmp/tsdf_open3d.npz")
K = data["K"]
T_grid_cam = data["T_world_cam"].copy()
T_grid_cam[:3, 3] -= data["origin"]  # the grid frame: world axes, origin at the cube's corner
extrinsic = np.linalg.inv(T_grid_cam)
intrinsic = o3d.camera.PinholeCameraIntrinsic(640, 480, K[0, 0], K[1, 1], K[0, 2], K[1, 2])
integration = o3d.pipelines.integration
for index in range(3):
    depth = o3d.geometry.Image(data[f"depth{index}"].astype(np.float32))
    colour = o3d.geometry.Image(np.zeros((480, 640, 3), np.uint8))
    start = time.perf_counter()
    for _ in range(20):
        volume = integration.UniformTSDFVolume(length=0.3, resolution=40, sdf_trunc=0.03,
                                               color_type=integration.TSDFVolumeColorType.NoColor)
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(colour, depth, depth_scale=1.0, depth_trunc=2.0,
                                                                  convert_rgb_to_intensity=False)
        volume.integrate(rgbd, intrinsic, extrinsic)
    ms = (time.perf_counter() - start) / 20 * 1e3
    cloud = volume.extract_voxel_point_cloud()  # (tsdf + 1) / 2 of the voxels VGN feeds, as colours
    ijk = np.floor(np.asarray(cloud.points) / 0.0075).astype(int)
    theirs = np.zeros((40, 40, 40), np.float32)
    theirs[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = np.asarray(cloud.colors)[:, 0]
    ours = data[f"ours{index}"]
    both = (theirs > 0) & (ours > 0)
    print(f"scene {index}: Open3D {ms:.1f} ms per view; voxels in the input: ours {int((ours > 0).sum())}, "
          f"Open3D {int((theirs > 0).sum())}, in one only {int(((theirs > 0) != (ours > 0)).sum())}; "
          f"largest difference where both {np.abs(theirs - ours)[both].max():.1e}")
