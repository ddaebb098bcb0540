"""The household grasp families and their self-collision filter: geometry of the poses, and the gripper's
opening and the approach distances read from their one source."""

import numpy as np

from kgn_bench.execution import GRASP_DEPTH, PREGRASP_DISTANCE
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.base import GraspDensity
from kgn_bench.shapes.household.families import (
    MIN_APPROACH_EXTENT,
    PINCH_CLEARANCE,
    box_family,
    gripper_sweep_free,
    on_axis,
    tube_family,
)


def test_tube_family_approaches_the_centre_line_across_the_tangent():
    centres = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]])
    tangents = np.tile([1.0, 0.0, 0.0], (2, 1))
    refs = np.tile([0.0, 0.0, 1.0], (2, 1))
    angles = np.array([0.0, np.pi / 2.0])
    poses, widths = tube_family(centres, tangents, refs, np.array([0.01, 0.02]), angles)
    assert poses.shape == (4, 4, 4)
    np.testing.assert_allclose(widths, [0.035, 0.035, 0.055, 0.055])
    np.testing.assert_allclose(poses[:, :3, 3], np.repeat(centres, 2, axis=0))
    np.testing.assert_allclose(poses[0, :3, 0], [0.0, 0.0, -1.0], atol=1e-12)  # β = 0: from +z towards the axis
    for R in poses[:, :3, :3]:
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(R[:, 2], np.cross(tangents[0], R[:, 0]), atol=1e-12)  # closing = t × approach


def test_box_family_never_approaches_through_a_thin_side():
    size = (0.06, 0.04, MIN_APPROACH_EXTENT / 2.0)
    poses, widths = box_family(np.eye(4), size, GraspDensity(2, 4))
    approaches = poses[:, :3, 0]
    assert np.all(np.abs(approaches[:, 2]) < 1e-12) and len(poses) == 2 * 2 * 2 * 2
    assert set(np.round(widths - PINCH_CLEARANCE, 6)) <= {0.06, 0.04, round(size[2], 6)}
    np.testing.assert_allclose(on_axis(poses, 0.5)[:, 2, 3], poses[:, 2, 3] + 0.5)


def test_sweep_filter_uses_the_gripper_opening_and_the_execution_distances():
    """A point beside a grasp is hit exactly where the finger sweeps: out to half the opening
    (``GRIPPER.opening``) plus the finger, from ``PREGRASP_DISTANCE`` behind to ``GRASP_DEPTH`` ahead."""
    pose, width = np.eye(4)[None], np.array([0.03])
    half_open = float(GRIPPER.opening(0.03)) / 2.0
    z = half_open + GRIPPER.finger_thickness / 2.0

    def free(x, z=z):
        return bool(gripper_sweep_free(np.array([[x, 0.0, z]]), pose, width)[0])

    assert not free(0.0) and not free(GRASP_DEPTH - 0.002)
    assert free(GRASP_DEPTH + 0.002)  # past the push
    assert not free(-GRIPPER.finger_length - PREGRASP_DISTANCE + 0.002)
    assert free(-GRIPPER.finger_length - PREGRASP_DISTANCE - GRIPPER.palm_depth - 0.05, z=0.2)
    assert free(0.0, z=half_open + GRIPPER.finger_thickness + 0.002)  # outside the open finger
    assert free(0.0, z=(0.03 - PINCH_CLEARANCE) / 2.0)  # the pinched part itself
