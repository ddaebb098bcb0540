"""The TSDF of a flat table seen from above, from the side and from two views agrees with the closed form."""

import numpy as np
import pytest

from kgn_bench.camera import Intrinsics, look_at
from kgn_bench.geometry import make_pose
from kgn_bench.tsdf import TSDFVolume, VoxelGrid

CAM = Intrinsics(fx=540.0, fy=540.0, cx=319.5, cy=239.5, width=640, height=480)
GRID = VoxelGrid()  # 30 cm, 40³, τ = 3 cm
CORNER = np.array([-0.15, -0.15, -0.06])  # the table top z = 0 lies between voxel layers 7 and 8


def _table_depth(T_world_cam: np.ndarray) -> np.ndarray:
    """Planar depth of the plane z = 0 seen from ``T_world_cam`` (0 where a ray misses it)."""
    u, v = np.meshgrid(np.arange(CAM.width), np.arange(CAM.height))
    rays = np.stack([(u - CAM.cx) / CAM.fx, (v - CAM.cy) / CAM.fy, np.ones_like(u, float)], axis=-1)
    R, t = T_world_cam[:3, :3], T_world_cam[:3, 3]
    dz = rays @ R[2]  # world z per unit of planar depth
    depth = np.where(dz < -1e-9, -t[2] / np.where(dz < -1e-9, dz, -1.0), 0.0)
    return depth


def _volume() -> TSDFVolume:
    return TSDFVolume(GRID, make_pose(t=CORNER))


def test_top_view_gives_the_height_above_the_table():
    T = look_at(np.array([0.0, 0.0, 0.6]), np.zeros(3))
    vol = _volume()
    vol.integrate(_table_depth(T), CAM, T)
    i = j = GRID.resolution // 2  # the column under the camera: the ray factor is ~1 there
    z = CORNER[2] + (np.arange(GRID.resolution) + 0.5) * GRID.voxel
    expected = np.clip(z / GRID.truncation, -np.inf, 1.0)
    seen = z >= -GRID.truncation
    ray = np.sqrt(1 + 2 * (0.5 * GRID.voxel / 0.6) ** 2)
    np.testing.assert_allclose(vol.tsdf[i, j, seen], np.minimum(1.0, expected[seen] * ray), atol=2e-3)
    assert vol.weight[i, j, seen].min() == 1.0
    assert vol.weight[i, j, ~seen].max() == 0.0, "voxels more than τ behind the surface stay unobserved"


def test_network_input_keeps_the_surface_band_only():
    T = look_at(np.array([0.0, 0.0, 0.6]), np.zeros(3))
    vol = _volume()
    vol.integrate(_table_depth(T), CAM, T)
    x = vol.network_input()
    assert x.dtype == np.float32 and x.shape == (40, 40, 40)
    column = x[20, 20]
    # Layers 4..11 (z from −2.6 to +2.6 cm) lie within the band; below, the voxels are more than τ behind the
    # table and unobserved; above, free space far from any surface: both read 0.
    assert np.all(column[:4] == 0) and np.all(column[4:12] > 0) and np.all(column[12:] == 0)
    assert int(np.argmin(np.abs(column - 0.5))) in (7, 8)  # z = −0.375 and +0.375 cm


def test_two_views_average_and_count():
    vol = _volume()
    for eye in ([0.0, 0.0, 0.6], [0.3, -0.3, 0.45]):
        T = look_at(np.array(eye), np.zeros(3))
        vol.integrate(_table_depth(T), CAM, T)
    assert vol.weight.max() == 2.0
    column = vol.tsdf[20, 20]
    z = CORNER[2] + (np.arange(40) + 0.5) * GRID.voxel
    near = np.abs(z) < 0.02
    # Along any ray the signed distance to a plane is the height divided by the cosine of the ray's
    # angle to the normal: it is at least the height and the same sign.
    assert np.all(np.sign(column[near]) == np.sign(z[near]))
    assert np.all(np.abs(column[near]) >= np.abs(z[near] / GRID.truncation) - 2e-3)


def test_depth_of_the_wrong_shape_is_refused():
    T = look_at(np.array([0.0, 0.0, 0.6]), np.zeros(3))
    with pytest.raises(ValueError, match="640×480"):
        _volume().integrate(np.ones((10, 10)), CAM, T)


def test_missing_depth_leaves_voxels_unobserved():
    T = look_at(np.array([0.0, 0.0, 0.6]), np.zeros(3))
    depth = _table_depth(T)
    depth[:, :320] = np.nan
    vol = _volume()
    vol.integrate(depth, CAM, T)
    assert vol.weight[:, :, :].sum() > 0
    # Image columns u < 320 look at world x < 0 (camera x = world x for a top view from look_at).
    assert vol.weight[:18].max() == 0.0 and vol.weight[22:].min() >= 0.0
