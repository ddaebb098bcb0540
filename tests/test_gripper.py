import numpy as np

from kgn_bench.geometry import make_pose, rot_z
from kgn_bench.gripper import GRIPPER


def test_proxy_box_spans_behind_fingertips():
    corners = GRIPPER.proxy_corners(np.eye(4)[None], np.array([0.06]))[0]
    np.testing.assert_allclose(corners.min(0), [-0.10, -0.01, -0.05])
    np.testing.assert_allclose(corners.max(0), [0.0, 0.01, 0.05])


def test_proxy_corners_follow_pose():
    T = make_pose(rot_z(np.pi / 2), [1.0, 0.0, 0.0])
    corners = GRIPPER.proxy_corners(T[None], np.array([0.0]))[0]
    # +x of the grasp is world +y: the box lies at world y in [-0.1, 0]
    np.testing.assert_allclose(corners[:, 1].min(), -0.10)
    np.testing.assert_allclose(corners[:, 1].max(), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.ptp(corners[:, 0]), 0.02, atol=1e-12)


def test_opening_adds_the_margin_up_to_the_maximum():
    np.testing.assert_allclose(GRIPPER.opening(0.05), 0.05 + GRIPPER.open_margin)
    np.testing.assert_allclose(GRIPPER.opening(GRIPPER.max_width), GRIPPER.max_width)
    np.testing.assert_allclose(GRIPPER.opening(np.array([0.0, 0.195])), [GRIPPER.open_margin, GRIPPER.max_width])


def test_a_swept_box_covers_the_path_from_the_pregrasp():
    palm = GRIPPER.palm_box()
    swept = palm.swept(0.1)
    lo, hi = swept.centre - swept.half, swept.centre + swept.half
    np.testing.assert_allclose(hi, palm.centre + palm.half)  # ends where the box ends at the grasp
    np.testing.assert_allclose(lo, palm.centre - palm.half - [0.1, 0.0, 0.0])  # starts 10 cm back along −x
