import numpy as np
import pytest

from kgn_bench.camera import REALSENSE, CameraSampler, Intrinsics, convert_camera_frame, look_at, orbit_pose
from kgn_bench.geometry import invert_pose, project, transform_points


def test_convert_camera_frame_is_an_involution_and_flips_y_z():
    T = look_at(np.array([0.3, -0.4, 0.7]), np.zeros(3))
    np.testing.assert_allclose(convert_camera_frame(convert_camera_frame(T)), T)
    mj = convert_camera_frame(T)
    # MuJoCo looks along −z: its −z axis is OpenCV's +z (the optical axis); y flips
    np.testing.assert_allclose(-mj[:3, 2], T[:3, 2])
    np.testing.assert_allclose(-mj[:3, 1], T[:3, 1])
    np.testing.assert_allclose(mj[:3, 0], T[:3, 0])


@pytest.mark.parametrize("elev_deg", [30.0, 60.0, 89.0, 90.0])
def test_orbit_pose_looks_at_origin_with_zero_roll(elev_deg):
    T = orbit_pose(0.8, np.deg2rad(elev_deg), 1.1)
    assert np.linalg.norm(T[:3, 3]) == pytest.approx(0.8)
    np.testing.assert_allclose(T[:3, 2], -T[:3, 3] / 0.8, atol=1e-12)  # optical axis through the origin
    assert abs(T[2, 0]) < 1e-12  # image x horizontal
    assert T[2, 1] <= 1e-12  # image down points downwards in the world
    uv = project(transform_points(invert_pose(T), np.zeros(3))[None], REALSENSE.K)[0]
    np.testing.assert_allclose(uv, [REALSENSE.cx, REALSENSE.cy], atol=1e-9)
    if elev_deg < 90:
        np.testing.assert_allclose(T[:3, :3], look_at(T[:3, 3], np.zeros(3))[:3, :3], atol=1e-9)


def test_camera_sampler_respects_ranges(rng):
    poses = CameraSampler().sample(rng, 200)
    d = np.linalg.norm(poses[:, :3, 3], axis=1)
    elev = np.rad2deg(np.arcsin(poses[:, 2, 3] / d))
    assert d.min() >= 0.6 and d.max() <= 1.0
    assert elev.min() >= 30 - 1e-9 and elev.max() <= 90 + 1e-9


def test_intrinsics_validation_and_dict():
    assert Intrinsics.from_dict(REALSENSE.to_dict()) == REALSENSE
    with pytest.raises(ValueError):
        Intrinsics(0, 1, 0, 0, 10, 10)


def test_a_far_plane_reads_its_distance_beyond_it_and_where_nothing_is_seen():
    from kgn_bench.camera import clip_far

    depth = np.array([[0.0, 0.5, 1.99], [2.0, 2.5, 3.4]], dtype=np.float32)
    np.testing.assert_array_equal(clip_far(depth, 2.0), np.array([[2.0, 0.5, 1.99], [2.0, 2.0, 2.0]], np.float32))
    assert clip_far(depth, 2.0).dtype == np.float32
    assert clip_far(depth, 0.0) is depth


def test_crop_depth_keeps_the_pixels_whose_points_lie_in_the_box():
    from kgn_bench.camera import crop_depth

    K = REALSENSE.K
    T = look_at(np.array([0.0, -0.6, 0.6]), np.zeros(3))  # T_world_cam looking at the origin from above
    depth = np.full((REALSENSE.height, REALSENSE.width), 0.0)
    rows = np.arange(REALSENSE.height)
    depth[:, :] = np.linspace(0.5, 1.2, REALSENSE.height)[:, None]
    depth[0, 0] = 0.0
    out = crop_depth(depth, K, T, np.array([-0.1, -0.1, -0.5]), np.array([0.1, 0.1, 0.5]))
    from kgn_bench.geometry import backproject, transform_points

    p = transform_points(T, backproject(depth, K).reshape(-1, 3)).reshape(*depth.shape, 3)
    inside = np.all(np.abs(p[..., :2]) <= 0.1, axis=-1) & (np.abs(p[..., 2]) <= 0.5) & (depth > 0)
    assert 0 < inside.sum() < inside.size and rows.size
    np.testing.assert_array_equal(out > 0, inside)
    np.testing.assert_array_equal(out[inside], depth[inside])
