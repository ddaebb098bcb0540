"""The work cell as compiled by MuJoCo: arm joints and limits, forward kinematics, TCP at the fingertip
midpoint, jaw travel, and the place bin."""

import mujoco
import numpy as np
import pytest

from kgn_bench.gripper import GRIPPER
from kgn_bench.sim.robot import (
    ARM_JOINTS,
    BASE_POSITION,
    BIN,
    PARK_Q,
    READY_Q,
    RobotIndex,
    add_workcell,
    robot_only_model,
)
from kgn_bench.sim.scene import Scene

# Franka FCI joint limits, as written in assets/arm7.xml
PANDA_LIMITS = np.array([
    (-2.8973, 2.8973), (-1.7628, 1.7628), (-2.8973, 2.8973), (-3.0718, -0.0698),
    (-2.8973, 2.8973), (-0.0175, 3.7525), (-2.8973, 2.8973),
])  # fmt: skip


@pytest.fixture(scope="module")
def cell():
    scene = Scene([], extend=add_workcell)
    return scene, RobotIndex(scene.model)


def _set(scene, robot, q_arm, opening=0.0):
    d = scene.data
    d.qpos[robot.arm_qpos] = q_arm
    d.qpos[robot.finger_qpos] = opening / 2.0
    mujoco.mj_forward(scene.model, d)
    s = robot.tcp_site
    return d.site_xpos[s].copy(), d.site_xmat[s].reshape(3, 3).copy()


def test_seven_arm_joints_with_panda_limits(cell):
    scene, robot = cell
    m = scene.model
    ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "arm7/" + n) for n in ARM_JOINTS]
    assert min(ids) >= 0 and len(set(ids)) == 7
    assert all(m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE for j in ids)
    assert all(m.jnt_limited[j] for j in ids)
    np.testing.assert_allclose(robot.arm_limits, PANDA_LIMITS)
    assert tuple(robot.arm_limits[3]) == (-3.0718, -0.0698)
    # the servos cannot be commanded outside the limits either
    np.testing.assert_allclose(m.actuator_ctrlrange[robot.arm_actuators], PANDA_LIMITS)
    for q in (READY_Q, PARK_Q):
        assert np.all(q > PANDA_LIMITS[:, 0]) and np.all(q < PANDA_LIMITS[:, 1])


def test_robot_index_in_both_models():
    ro = RobotIndex(robot_only_model(), prefix="")
    assert len(ro.arm_qpos) == 7 and len(ro.pad_geoms) == 2 and ro.tcp_site >= 0
    with pytest.raises(ValueError, match="no robot"):
        RobotIndex(Scene([]).model)


def test_forward_kinematics_at_zero(cell):
    """At q = 0 the Panda chain is straight up: flange 0.333 + 0.316 + 0.384 − 0.107 = 0.926 m above the
    base, offset a6 = 0.088 m along x, pointing down; the TCP is tcp_offset further down the flange axis."""
    scene, robot = cell
    p, R = _set(scene, robot, np.zeros(7))
    expected = BASE_POSITION + np.array([0.088, 0.0, 0.926 - GRIPPER.tcp_offset])
    np.testing.assert_allclose(p, expected, atol=1e-6)
    np.testing.assert_allclose(R[:, 0], [0.0, 0.0, -1.0], atol=1e-9)  # approach: down the flange axis
    # closing axis: flange y (world −y at q = 0) turned −45° about the flange axis
    np.testing.assert_allclose(R[:, 2], np.array([1.0, -1.0, 0.0]) / np.sqrt(2.0), atol=1e-9)
    assert np.linalg.det(R) == pytest.approx(1.0)


def test_ready_pose_points_down_over_the_table(cell):
    scene, robot = cell
    p, R = _set(scene, robot, READY_Q)
    assert R[:, 0] @ [0.0, 0.0, -1.0] > np.cos(np.deg2rad(2.0))
    assert abs(p[0]) < 0.2 and abs(p[1]) < 0.1 and 0.2 < p[2] < 0.6


@pytest.mark.parametrize("width", [0.0, 0.03, 0.08, GRIPPER.max_width])
def test_tcp_is_the_fingertip_midpoint(cell, width):
    scene, robot = cell
    p, R = _set(scene, robot, READY_Q, opening=width)
    assert robot.opening(scene.data) == pytest.approx(width)
    m, d = scene.model, scene.data
    faces, tips = [], []
    for side, g in zip((+1, -1), robot.pad_geoms):
        centre = R.T @ (d.geom_xpos[g] - p)  # pad centre in the TCP frame
        axes = R.T @ d.geom_xmat[g].reshape(3, 3)
        np.testing.assert_allclose(np.abs(axes), np.eye(3), atol=1e-9)  # pads aligned with the TCP frame
        half = m.geom_size[g]
        assert np.sign(centre[2]) == side or width == 0.0
        faces.append(centre[2] - side * half[2])  # inner face along the closing axis
        tips.append(centre[0] + half[0])  # fingertip: front end along the approach axis
        assert centre[1] == pytest.approx(0.0, abs=1e-9)
        assert half[1] == pytest.approx(GRIPPER.finger_breadth / 2.0)
    np.testing.assert_allclose(faces, [width / 2.0, -width / 2.0], atol=1e-9)
    np.testing.assert_allclose(tips, [0.0, 0.0], atol=1e-9)


def test_jaw_travel(cell):
    scene, robot = cell
    m = scene.model
    j = m.jnt_qposadr.tolist()
    fingers = [j.index(a) for a in robot.finger_qpos]
    travel = sum(m.jnt_range[f][1] for f in fingers)
    assert GRIPPER.max_width >= 0.15
    assert travel == pytest.approx(GRIPPER.max_width)
    assert m.actuator_ctrlrange[robot.gripper_actuator][1] == pytest.approx(GRIPPER.max_width / 2.0)
    # the palm is wide enough to carry both fingers fully open
    assert GRIPPER.palm_half_span >= GRIPPER.max_width / 2.0 + GRIPPER.finger_thickness


def test_robot_collides_with_the_world_but_not_itself(cell):
    scene, robot = cell
    m = scene.model
    pads = set(robot.pad_geoms.tolist())

    def pair(a, b):  # MuJoCo's filter: either geom's contype matches the other's conaffinity
        return bool(m.geom_contype[a] & m.geom_conaffinity[b] or m.geom_contype[b] & m.geom_conaffinity[a])

    active = [g for g in robot.geoms if m.geom_contype[g] or m.geom_conaffinity[g]]
    assert pads <= set(active) and len(active) >= 4  # pads, palm and wrist links at least
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    for g in active:
        assert pair(g, scene.table_geom) and pair(g, floor)
        assert not any(pair(g, h) for h in active)  # never robot ↔ robot


def test_bin_contains():
    cx, cy = BIN.centre
    assert BIN.contains(np.array([cx, cy, 0.03]))
    assert BIN.contains(np.array([cx + BIN.half - 1e-3, cy - BIN.half + 1e-3, 0.0]))
    assert not BIN.contains(np.array([cx + BIN.half + 0.01, cy, 0.03]))
    assert not BIN.contains(np.array([cx, cy + BIN.half + 0.01, 0.03]))
    assert BIN.contains(np.array([cx, cy, BIN.height + 0.05]))  # on a pile of objects already in the bin
    assert not BIN.contains(np.array([cx, cy, BIN.pile_height + 0.01]))  # held high above the bin
    assert not BIN.contains(np.array([cx, cy, -0.05]))
    assert not BIN.contains(np.zeros(3))  # the table centre


def test_bin_geoms_match_the_bin(cell):
    scene, _ = cell
    m = scene.model

    def geom(name):
        g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
        assert g >= 0, name
        return m.geom_pos[g], m.geom_size[g]

    pos, size = geom("bin_floor")
    assert pos[2] + size[2] == pytest.approx(0.0)  # floor top at z = 0
    np.testing.assert_allclose(pos[:2], BIN.centre)
    inner = []
    for k in range(4):
        pos, size = geom(f"bin_wall{k}")
        assert pos[2] + size[2] == pytest.approx(BIN.height)
        d = pos[:2] - BIN.centre
        axis = int(np.argmax(np.abs(d)))
        inner.append(abs(d[axis]) - size[axis])
    np.testing.assert_allclose(inner, BIN.half)  # the walls' inner faces bound what contains() accepts
