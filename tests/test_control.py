"""mink IK on the robot-only model, the minimum-jerk profile, and motion primitives tracked by the servos of a
real work-cell scene."""

import numpy as np
import pytest

from kgn_bench.geometry import make_pose, rotation_angle
from kgn_bench.gripper import GRIPPER
from kgn_bench.sim.control import CONTROL_DT, IK, JOINT_SPEED, Executor, MotionAborted, min_jerk, to_base
from kgn_bench.sim.robot import BASE_POSITION, PARK_Q, READY_Q, RobotIndex, add_workcell
from kgn_bench.sim.scene import Scene


@pytest.fixture(scope="module")
def ik():
    return IK()


@pytest.fixture
def executor(ik):
    scene = Scene([], extend=add_workcell)
    ex = Executor(scene, ik)
    ex.reset(READY_Q)
    return ex


def _top_down(ik, xyz):
    T = ik.tcp_pose(READY_Q)  # READY_Q points the gripper down
    T[:3, 3] = xyz
    return T


def _errors(A, B):
    return float(np.linalg.norm(A[:3, 3] - B[:3, 3])), float(np.rad2deg(rotation_angle(A[:3, :3], B[:3, :3])))


def test_min_jerk_profile():
    assert min_jerk(0.0) == 0.0 and min_jerk(1.0) == 1.0 and min_jerk(0.5) == pytest.approx(0.5)
    assert min_jerk(-1.0) == 0.0 and min_jerk(2.0) == 1.0  # clipped
    s = np.linspace(0.0, 1.0, 1001)
    y = min_jerk(s)
    assert np.all(np.diff(y) >= 0.0)
    v = np.gradient(y, s)
    assert v[0] == pytest.approx(0.0, abs=1e-2) and v[-1] == pytest.approx(0.0, abs=1e-2)  # rest to rest
    assert v.max() == pytest.approx(1.875, abs=1e-3)  # the peak speed used to time joint moves
    np.testing.assert_allclose(min_jerk(1.0 - s), 1.0 - y, atol=1e-12)  # symmetric


def test_to_base_is_a_translation():
    T = make_pose(np.eye(3), [0.1, 0.2, 0.3])
    np.testing.assert_allclose(to_base(T)[:3, 3], np.array([0.1, 0.2, 0.3]) - BASE_POSITION)
    assert T[0, 3] == 0.1  # input untouched


def test_ik_forward_kinematics_matches_the_work_cell(ik, executor):
    """FK of the robot-only model, moved to the base position, equals the TCP site of the compiled scene."""
    rng = np.random.default_rng(3)
    lo, hi = ik.index.arm_limits.T
    scene, robot = executor.scene, executor.robot
    for _ in range(5):
        q = rng.uniform(lo, hi)
        executor.reset(q)
        np.testing.assert_allclose(ik.tcp_pose(q), executor.tcp_pose(), atol=1e-9)
    assert robot.opening(scene.data) == pytest.approx(GRIPPER.max_width)


@pytest.mark.parametrize("xyz", [(0.0, 0.0, 0.05), (0.15, 0.2, 0.02), (-0.2, -0.25, 0.15)])
def test_ik_reaches_top_down_poses(ik, xyz):
    target = _top_down(ik, xyz)
    r = ik.solve(target)
    assert r.ok
    pos, ang = _errors(ik.tcp_pose(r.q), target)  # checked by FK, not by the solver's own report
    assert pos < 1e-3 and ang < 1.0
    assert r.position_error == pytest.approx(pos, abs=1e-9)
    lo, hi = ik.index.arm_limits.T
    assert np.all(r.q >= lo) and np.all(r.q <= hi)


def test_ik_reports_unreachable_poses(ik):
    far = _top_down(ik, (BASE_POSITION[0] + 1.5, 0.0, 0.1))
    r = ik.solve(far)
    assert not r.ok and r.position_error > 0.3
    lo, hi = ik.index.arm_limits.T
    assert np.all(r.q >= lo - 1e-6) and np.all(r.q <= hi + 1e-6)  # still a valid configuration
    # just out of reach: the Panda reaches about 0.86 m from its shoulder
    assert not ik.solve(_top_down(ik, (BASE_POSITION[0] + 1.0, 0.0, 0.0))).ok


def test_ik_step_respects_joint_speed(ik):
    far = _top_down(ik, (0.3, 0.3, 0.0))
    q1 = ik.step(READY_Q, far)
    assert np.any(q1 != READY_Q)
    assert np.all(np.abs(q1 - READY_Q) <= JOINT_SPEED * CONTROL_DT + 1e-6)


def test_move_joints_reaches_the_commanded_pose(ik, executor):
    executor.reset(PARK_Q)
    target = _top_down(ik, (0.1, 0.15, 0.05))
    r = ik.solve(target)
    assert r.ok
    t0 = executor.scene.data.time
    executor.move_joints(r.q)
    executor.wait(0.3)
    assert executor.scene.data.time > t0 + 0.3
    np.testing.assert_allclose(executor.q_ref, r.q)
    pos, ang = _errors(executor.tcp_pose(), target)
    assert pos < 3e-3 and ang < 1.0


def test_move_linear_follows_a_straight_line(ik, executor):
    start = executor.tcp_pose()
    goal = start.copy()
    goal[:3, 3] += (0.15, -0.1, -0.2)
    path = []
    executor.on_tick = lambda: path.append(executor.tcp_pose()[:3, 3].copy())
    executor.move_linear(goal, 0.8)
    executor.wait(0.3)
    assert len(path) == 80 + 30  # one tick per CONTROL_DT
    pos, ang = _errors(executor.tcp_pose(), goal)
    assert pos < 3e-3 and ang < 1.0
    a, b = start[:3, 3], goal[:3, 3]
    u = (b - a) / np.linalg.norm(b - a)
    off_line = [np.linalg.norm((p - a) - ((p - a) @ u) * u) for p in path]
    assert max(off_line) < 5e-3


def test_arm_holds_still_under_gravity(executor):
    before = executor.tcp_pose()
    executor.wait(1.0)
    pos, ang = _errors(executor.tcp_pose(), before)
    assert pos < 1e-3 and ang < 0.2


def test_set_gripper_opens_and_closes(executor):
    robot: RobotIndex = executor.robot
    data = executor.scene.data
    for w in (0.05, 0.0, 0.12, GRIPPER.max_width, 0.5):
        executor.set_gripper(w, 0.3)
        executor.wait(0.3)
        assert robot.opening(data) == pytest.approx(min(w, GRIPPER.max_width), abs=2e-3)
        left, right = data.qpos[robot.finger_qpos]
        assert left == pytest.approx(right, abs=1e-3)  # symmetric jaws


def test_monitor_aborts_a_motion(ik, executor):
    ticks = []

    def monitor():
        ticks.append(executor.scene.data.time)
        return "collision" if len(ticks) == 7 else None

    with pytest.raises(MotionAborted) as e:
        executor.move_joints(PARK_Q, monitor=monitor)
    assert e.value.reason == "collision" and len(ticks) == 7
    assert not np.allclose(executor.q_ref, PARK_Q)  # stopped part-way
