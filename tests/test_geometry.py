import numpy as np
import pytest

from kgn_bench.geometry import (
    axis_align,
    backproject,
    invert_pose,
    make_pose,
    matrix_from_quat_wxyz,
    project,
    quat_wxyz_from_matrix,
    quats_wxyz_from_matrices,
    rot_x,
    rot_y,
    rot_z,
    rotation_angle,
    transform_points,
)


def _random_rotation(rng):
    q = rng.normal(size=4)
    return matrix_from_quat_wxyz(q)


def test_elementary_rotations_turn_the_right_way():
    np.testing.assert_allclose(rot_z(np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(rot_x(np.pi / 2) @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(rot_y(np.pi / 2) @ [0, 0, 1], [1, 0, 0], atol=1e-12)
    assert rot_z(np.array([0.1, 0.2])).shape == (2, 3, 3)


def test_axis_align_columns_are_signed_parent_axes():
    R = axis_align((-3, 2, 1))
    np.testing.assert_array_equal(R[:, 0], [0, 0, -1])
    np.testing.assert_array_equal(R[:, 1], [0, 1, 0])
    np.testing.assert_array_equal(R[:, 2], [1, 0, 0])
    with pytest.raises(ValueError):
        axis_align((1, 2, -3))  # left-handed
    with pytest.raises(ValueError):
        axis_align((1, 2, 4))


def test_quaternion_round_trip(rng):
    for _ in range(50):
        R = _random_rotation(rng)
        np.testing.assert_allclose(matrix_from_quat_wxyz(quat_wxyz_from_matrix(R)), R, atol=1e-12)
    assert quat_wxyz_from_matrix(rot_x(np.pi))[0] >= 0


def test_batched_quaternions_are_the_single_ones_bit_for_bit(rng):
    R = np.stack([_random_rotation(rng) for _ in range(200)] + [rot_x(np.pi), np.eye(3)])
    batch = quats_wxyz_from_matrices(R)
    assert np.array_equal(batch, np.stack([quat_wxyz_from_matrix(r) for r in R]))
    assert quats_wxyz_from_matrices(np.zeros((0, 3, 3))).shape == (0, 4)


def test_pose_inverse_and_rotation_angle(rng):
    T = make_pose(_random_rotation(rng), rng.normal(size=3))
    np.testing.assert_allclose(invert_pose(T) @ T, np.eye(4), atol=1e-12)
    stack = np.stack([T, T])
    np.testing.assert_allclose(invert_pose(stack)[1], invert_pose(T))
    p = rng.normal(size=(5, 3))
    np.testing.assert_allclose(transform_points(invert_pose(T), transform_points(T, p)), p, atol=1e-12)
    assert rotation_angle(np.eye(3), rot_z(0.3)) == pytest.approx(0.3)


def test_project_backproject_round_trip():
    K = np.array([[600.0, 0, 320.5], [0, 610.0, 240.25], [0, 0, 1]])
    depth = np.full((48, 64), 0.8, dtype=np.float32)
    depth[10, 20] = 0.0
    pts = backproject(depth, K)
    uv = project(pts[depth > 0], K)
    v, u = np.nonzero(depth > 0)
    np.testing.assert_allclose(uv, np.stack([u, v], 1), atol=1e-9)
    np.testing.assert_array_equal(pts[10, 20], 0.0)
