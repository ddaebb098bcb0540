"""The floating hand and GIGA's execution with it: real MuJoCo, the Panda hand, one object on the table."""

from __future__ import annotations

import numpy as np
import pytest

from kgn_bench import giga
from kgn_bench.geometry import make_pose
from kgn_bench.gripper import GRIPPER, PANDA_HAND
from kgn_bench.shapes.primitives import Cuboid
from kgn_bench.sim.floating_hand import FloatingHand, add_floating_cell, execute_grasp, lift_pose
from kgn_bench.sim.placement import settle
from kgn_bench.sim.scene import Scene, SceneObject

DOWN = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
"""A grasp frame approaching straight down (+x = −z world), closing along world x."""


def _scene(shape, g=PANDA_HAND) -> tuple[Scene, FloatingHand]:
    z = -shape.lowest_point(np.eye(3)) + 0.001
    scene = Scene([SceneObject(shape, (0.7, 0.3, 0.2), make_pose(t=np.array([0.0, 0.0, z])))],
                  extend=lambda root: add_floating_cell(root, g))
    hand = FloatingHand(scene, g)
    hand.park()
    settle(scene)
    return scene, hand


def _top_grasp(scene: Scene, depth: float) -> np.ndarray:
    """Straight down over object 0 (a box with its frame at its centre), the fingertips ``depth`` below its top."""
    T = scene.object_pose(0)
    height = 2.0 * (T[2, 3])
    return make_pose(DOWN, np.array([T[0, 3], T[1, 3], height - depth]))


def test_panda_hand_geometry():
    assert PANDA_HAND.max_width == pytest.approx(0.08)
    assert PANDA_HAND.finger_length == pytest.approx(0.05)
    assert PANDA_HAND.palm_half_span > PANDA_HAND.max_width / 2 + PANDA_HAND.finger_thickness
    assert GRIPPER.palm_half_span == pytest.approx(GRIPPER.max_width / 2 + GRIPPER.finger_thickness + 0.005)


def test_top_grasp_on_a_box_holds_and_names_the_object():
    scene, hand = _scene(Cuboid((0.04, 0.05, 0.10)))
    z0 = scene.object_pose(0)[2, 3]
    heights: list[float] = []
    hand.on_tick = lambda: heights.append(scene.object_pose(0)[2, 3])
    out = execute_grasp(hand, _top_grasp(scene, 0.03))
    assert out.reason is None, out
    assert max(heights) - z0 == pytest.approx(giga.LIFT_DISTANCE, abs=0.01)  # carried up the full lift
    assert out.object == 0
    assert out.opening == pytest.approx(0.04, abs=0.004)  # the jaws rest on the box's 4 cm side
    assert np.linalg.norm(hand.tcp_pose()[:3, 3] - [0.0, 0.0, 20.0]) < 1e-6  # parked afterwards


def test_grasp_beside_the_object_misses():
    scene, hand = _scene(Cuboid((0.04, 0.05, 0.10)))
    T = _top_grasp(scene, 0.03)
    T[1, 3] += 0.12
    out = execute_grasp(hand, T)
    assert out.reason == "missed"


def test_object_wider_than_the_hand_collides_at_the_pregrasp_or_is_not_held():
    scene, hand = _scene(Cuboid((0.12, 0.12, 0.05)))
    T = _top_grasp(scene, 0.02)
    out = execute_grasp(hand, T, allow_contact=False)
    assert out.reason == "collision"
    assert "touched" in out.detail


def test_pregrasp_inside_the_object_is_a_collision():
    scene, hand = _scene(Cuboid((0.04, 0.05, 0.10)))
    T = _top_grasp(scene, 0.03)
    T[:3, 3] += 0.09 * T[:3, 0]  # so deep that the pre-grasp's fingers are inside the box
    out = execute_grasp(hand, T)
    assert out.reason == "collision"


def test_lift_goes_up_for_side_grasps_and_back_for_top_grasps():
    top = make_pose(DOWN, np.array([0.0, 0.0, 0.1]))
    assert np.allclose(lift_pose(top)[:3, 3], [0.0, 0.0, 0.1 + giga.LIFT_DISTANCE])
    side = make_pose(np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]), np.array([0.0, 0.0, 0.05]))
    assert side[:3, 0] @ np.array([0.0, 0.0, -1.0]) == pytest.approx(0.0)
    assert np.allclose(lift_pose(side)[:3, 3], [0.0, 0.0, 0.05 + giga.LIFT_DISTANCE])
    tilted = make_pose(DOWN, np.zeros(3))
    tilted[:3, :3] = np.array([[0.5, 0.0, np.sqrt(3) / 2], [0.0, 1.0, 0.0], [-np.sqrt(3) / 2, 0.0, 0.5]])
    assert np.allclose(lift_pose(tilted)[:3, 3], -giga.LIFT_DISTANCE * tilted[:3, 0])
