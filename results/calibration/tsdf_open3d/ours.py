"""Our side of the TSDF check: three GIGA scenes (side view, exact depth), each fused with ``kgn_bench.tsdf`` 20
times to time it; writes the depth images and our network inputs to /tmp/tsdf_open3d.npz for open3d_side.py."""

import time

import numpy as np

from kgn_bench import giga
from kgn_bench.data.vgn_generate import VGNDataConfig, _arranged_scene, side_view
from kgn_bench.geometry import make_pose
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.tsdf import TSDFVolume, VoxelGrid

config = VGNDataConfig(objects=("cuboid", "cylinder", "mug", "bottle"))
out: dict[str, np.ndarray] = {}
cam = side_view()
for index in range(3):
    scene, _, _ = _arranged_scene(config, index, np.random.default_rng([5, index]))
    with SceneRenderer(scene) as renderer:
        depth = renderer.render(cam).depth
    start = time.perf_counter()
    for _ in range(20):
        volume = TSDFVolume(VoxelGrid(), make_pose(t=giga.WORKSPACE_ORIGIN))
        volume.integrate(depth, scene.intrinsics, cam)
    print(f"scene {index}: ours {(time.perf_counter() - start) / 20 * 1e3:.1f} ms per view")
    out[f"depth{index}"] = depth
    out[f"ours{index}"] = volume.network_input()
out.update(K=scene.intrinsics.K, T_world_cam=cam, origin=giga.WORKSPACE_ORIGIN)
np.savez("/tmp/tsdf_open3d.npz", **out)
