"""The physics check of grasps: the close-hold-shake test with the benchmark's gripper in real MuJoCo."""

from __future__ import annotations

import numpy as np

from kgn_bench.geometry import make_pose, rotation_angle
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes import EVAL_DENSITY, PRIMITIVES
from kgn_bench.sim.grasp_verify import ShakeTest, _shake_rotations, _shake_targets, verify_grasps


def _cuboid():
    return PRIMITIVES["cuboid"].from_dims({"size": [0.08, 0.05, 0.04]})


def test_closed_form_cuboid_grasps_hold():
    shape = _cuboid()
    g = shape.grasps(EVAL_DENSITY)
    pick = np.random.default_rng(0).choice(len(g), 6, replace=False)
    assert verify_grasps(shape, g.poses[pick], g.widths[pick]).all()


def test_a_grasp_beside_the_object_closes_on_nothing():
    shape = _cuboid()
    g = shape.grasps(EVAL_DENSITY)
    away = g.poses[:3] @ make_pose(t=np.array([-0.15, 0.0, 0.0]))  # 15 cm back along the approach
    assert not verify_grasps(shape, away, g.widths[:3]).any()


def test_a_pinch_at_the_rim_of_a_sphere_slips():
    """Fingers meeting a 3 cm sphere 2.6 cm off its centre touch it where the surface is steep: the squeeze
    pushes it out. The same grasp through the centre holds."""
    shape = PRIMITIVES["sphere"].from_dims({"r": 0.03})
    centre = make_pose()
    off = make_pose(t=np.array([0.0, 0.026, 0.0]))
    held = verify_grasps(shape, np.stack([centre, off]), np.array([0.075, 0.075]))
    assert held.tolist() == [True, False]


def test_harder_shaking_drops_the_marginal_grasp():
    """Pinches of a 3 cm sphere from its centre out to 2.4 cm off it all hold the default shake; shaking 6 cm
    and 40° at 0.15 s per cycle loses the most marginal one, and 10 cm / 60° at 0.1 s loses all."""
    shape = PRIMITIVES["sphere"].from_dims({"r": 0.03})
    poses = np.stack([make_pose(t=np.array([0.0, y, 0.0])) for y in (0.0, 0.015, 0.024)])
    widths = np.full(3, 0.075)
    assert verify_grasps(shape, poses, widths).tolist() == [True, True, True]
    harsh = ShakeTest(shake_m=0.06, shake_deg=40.0, shake_period_s=0.15)
    assert verify_grasps(shape, poses, widths, harsh).tolist() == [True, True, False]
    brutal = ShakeTest(shake_m=0.1, shake_deg=60.0, shake_period_s=0.1)
    assert not verify_grasps(shape, poses, widths, brutal).any()


def test_a_gripper_that_starts_inside_the_object_fails():
    """A cuboid grasp pushed 6 cm deeper along its approach puts the palm 1 cm into the box: refused before
    closing. Allowing 10 cm of overlap, MuJoCo pushes the overlap apart into a wedge that "holds"."""
    shape = _cuboid()
    g = shape.grasps(EVAL_DENSITY)
    deep = g.poses[:1] @ make_pose(t=np.array([0.06, 0.0, 0.0]))
    assert not verify_grasps(shape, deep, g.widths[:1])[0]
    lax = ShakeTest(max_start_penetration=0.1)
    assert verify_grasps(shape, deep, g.widths[:1], lax)[0]


def test_the_shake_moves_the_hand_by_its_amplitude_about_the_grasp():
    """The hand's targets: 3 translation cycles of ±shake_m along the grasp's axes (its rotation kept), then 3
    turns of ±shake_deg about them (the TCP kept in place); every target is the grasp moved that much."""
    test = ShakeTest()
    T_grasp = make_pose(_cuboid().grasps(EVAL_DENSITY).poses[0][:3, :3], np.array([0.1, -0.2, 1.0]))
    targets = _shake_targets(T_grasp, test, _shake_rotations(test, 150))
    assert targets.shape == (900, 4, 4)
    tcp = targets @ make_pose(t=np.array([GRIPPER.tcp_offset, 0.0, 0.0]))
    moved = np.linalg.norm(tcp[:, :3, 3] - T_grasp[:3, 3], axis=1)
    turned = np.array([rotation_angle(T[:3, :3], T_grasp[:3, :3]) for T in tcp])
    assert np.isclose(moved[:450].max(), test.shake_m, rtol=1e-3)
    assert np.allclose(turned[:450], 0.0, atol=1e-7)
    assert np.allclose(moved[450:], 0.0, atol=1e-12)
    assert np.isclose(np.rad2deg(turned[450:].max()), test.shake_deg, rtol=1e-3)
