import numpy as np
import pytest

from kgn_bench.geometry import make_pose, rot_z
from kgn_bench.grasp import FLIP_X180, GraspSet, flip_180, keypoint_box, keypoints_in_frame


def test_keypoint_box_layout():
    np.testing.assert_allclose(
        keypoint_box(0.1), [[0, 0, 0.05], [0, 0, -0.05], [-0.1, 0, 0.05], [-0.1, 0, -0.05]]
    )
    with pytest.raises(ValueError):
        keypoint_box(0.0)


def test_flip_swaps_left_and_right_keypoints():
    T = make_pose(rot_z(0.7), [0.1, -0.2, 0.3])[None]
    k = keypoints_in_frame(T, 0.1)[0]
    kf = keypoints_in_frame(flip_180(T), 0.1)[0]
    np.testing.assert_allclose(kf[[1, 0, 3, 2]], k, atol=1e-12)
    np.testing.assert_allclose(flip_180(flip_180(T)), T)
    # approach axis unchanged, closing axis reversed
    np.testing.assert_allclose((T @ FLIP_X180)[0, :3, 0], T[0, :3, 0])
    np.testing.assert_allclose((T @ FLIP_X180)[0, :3, 2], -T[0, :3, 2])


def test_keypoints_scale_with_side_and_follow_pose():
    T = make_pose(np.eye(3), [1.0, 2.0, 3.0])[None]
    k = keypoints_in_frame(np.repeat(T, 2, 0), np.array([0.1, 0.2]))
    np.testing.assert_allclose(k[1] - T[0, :3, 3], 2 * (k[0] - T[0, :3, 3]))


def test_graspset_checks_shapes_and_filters():
    poses = np.repeat(np.eye(4)[None], 3, 0)
    g = GraspSet(poses, np.array([0.01, 0.02, 0.03]), np.array([True, False, True]))
    assert len(g.free()) == 1 and g.free().widths[0] == 0.02
    with pytest.raises(ValueError):
        GraspSet(poses, np.zeros(2), np.zeros(3, bool))
    T = make_pose(t=[0, 0, 1])
    assert g.transformed(T).poses[0, 2, 3] == 1.0
    assert len(GraspSet.concatenate([g, g])) == 6
    np.testing.assert_array_equal(g.subset(g.widths > 0.015).widths, [0.02, 0.03])
    np.testing.assert_array_equal(g.subset(np.array([2, 0])).collides, [True, True])


def test_grasp_rotation_error_respects_the_180_degree_symmetry():
    from kgn_bench.geometry import rot_x, rot_z
    from kgn_bench.grasp import grasp_rotation_error

    R = rot_z(0.3) @ rot_x(0.2)
    assert grasp_rotation_error(R, R @ rot_x(np.pi)) == pytest.approx(0.0, abs=1e-7)
    assert grasp_rotation_error(R, R @ rot_x(np.pi / 2)) == pytest.approx(np.pi / 2)
    assert grasp_rotation_error(R, R @ rot_x(0.7 * np.pi)) == pytest.approx(0.3 * np.pi)
    # about another axis the symmetry does not help
    assert grasp_rotation_error(R, R @ rot_z(0.4)) == pytest.approx(0.4)
    stack = grasp_rotation_error(np.stack([R, R]), np.stack([R, R @ rot_z(0.4)]))
    np.testing.assert_allclose(stack, [0.0, 0.4], atol=1e-7)
