"""Arm control: mink differential IK on the robot-only model, and motion primitives executed by the
position servos of a work-cell scene.

Poses are 4×4 ``T_world_tcp`` (world frame, TCP = grasp frame of ``gripper.py``). IK runs on the
robot-only model whose base is at its origin; ``to_base`` is the one conversion world → base.

Motion primitives command joint references at ``CONTROL_DT`` (100 Hz): joint-space moves follow a
minimum-jerk profile; Cartesian moves interpolate the TCP pose (position linearly, rotation along the
geodesic, minimum-jerk timing) and track it with one IK step per tick under joint position and velocity
limits. The physics model holds the arm up with gravity compensation; its servos only track.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mink
import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from kgn_bench.geometry import make_pose, rotation_angle
from kgn_bench.gripper import GRIPPER
from kgn_bench.sim.robot import BASE_POSITION, READY_Q, RobotIndex, robot_only_model
from kgn_bench.sim.scene import Scene

__all__ = ["CONTROL_DT", "IK", "Executor", "IKResult", "MotionAborted", "min_jerk", "to_base"]

CONTROL_DT = 0.01
"""Control period (s): one IK step and one joint reference per tick."""
JOINT_SPEED = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
"""Panda joint speed limits (rad/s, FCI)."""
T_WORLD_BASE = make_pose(np.eye(3), BASE_POSITION)


def to_base(T_world: np.ndarray) -> np.ndarray:
    """A world-frame pose expressed in the arm's base frame: ``T_base = T_world_base⁻¹ · T_world``."""
    out = np.array(T_world, dtype=float, copy=True)
    out[..., :3, 3] -= BASE_POSITION
    return out


def min_jerk(s: np.ndarray | float) -> np.ndarray | float:
    """Minimum-jerk time scaling ``10s³ − 15s⁴ + 6s⁵`` for ``s ∈ [0, 1]``."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s**2)


@dataclass(frozen=True)
class IKResult:
    """Joint configuration ``q`` (7,), whether it reached the target, and the residual errors (m, rad)."""

    q: np.ndarray
    ok: bool
    position_error: float
    rotation_error: float


class IK:
    """mink differential IK for the TCP: a frame task, a posture task towards ``READY_Q``, joint limits.

    ``solve`` iterates to convergence (a static IK query, for feasibility); ``step`` takes one
    velocity-limited step of ``CONTROL_DT`` towards a target (tracking).
    """

    def __init__(self, position_tolerance: float = 1e-3, rotation_tolerance: float = np.deg2rad(1.0)) -> None:
        model = robot_only_model()
        self.model = model
        self.index = RobotIndex(model, prefix="")
        self.configuration = mink.Configuration(model)
        self.frame_task = mink.FrameTask("gripper/tcp", "site", position_cost=1.0, orientation_cost=1.0,
                                         lm_damping=1e-2)
        self.posture_task = mink.PostureTask(model, cost=1e-2)
        self.posture_task.set_target(self._full(READY_Q))
        self.tasks = [self.frame_task, self.posture_task]
        velocities = {f"joint{i + 1}": float(v) for i, v in enumerate(JOINT_SPEED)}
        self.position_limit = mink.ConfigurationLimit(model, min_distance_from_limits=0.01)
        self.limits = [self.position_limit, mink.VelocityLimit(model, velocities)]
        self.position_tolerance = position_tolerance
        self.rotation_tolerance = rotation_tolerance

    def _full(self, q_arm: np.ndarray) -> np.ndarray:
        q = np.full(self.model.nq, GRIPPER.finger_travel / 2.0)  # fingers mid-stroke, clear of their limits
        q[self.index.arm_qpos] = q_arm
        return q

    def tcp_pose(self, q_arm: np.ndarray) -> np.ndarray:
        """Forward kinematics: ``T_world_tcp`` at arm configuration ``q_arm``."""
        self.configuration.update(self._full(q_arm))
        T = self.configuration.get_transform_frame_to_world("gripper/tcp", "site").as_matrix()
        return T_WORLD_BASE @ T

    def _set_target(self, T_world_tcp: np.ndarray) -> np.ndarray:
        T_base = to_base(T_world_tcp)
        self.frame_task.set_target(mink.SE3.from_matrix(T_base))
        return T_base

    def solve(self, T_world_tcp: np.ndarray, q_seed: np.ndarray = READY_Q, iterations: int = 60) -> IKResult:
        """Iterate IK from ``q_seed`` until the TCP reaches ``T_world_tcp`` within tolerance (or give up)."""
        T_base = self._set_target(T_world_tcp)
        self.configuration.update(self._full(q_seed))
        dt = 0.1
        pos_err = rot_err = np.inf
        for _ in range(iterations):
            v = mink.solve_ik(self.configuration, self.tasks, dt, "daqp", damping=1e-3,
                              limits=[self.position_limit])
            self.configuration.integrate_inplace(v, dt)
            T = self.configuration.get_transform_frame_to_world("gripper/tcp", "site").as_matrix()
            pos_err = float(np.linalg.norm(T[:3, 3] - T_base[:3, 3]))
            rot_err = float(rotation_angle(T[:3, :3], T_base[:3, :3]))
            if pos_err <= self.position_tolerance and rot_err <= self.rotation_tolerance:
                break
        q = self.configuration.q[self.index.arm_qpos].copy()
        lo, hi = self.index.arm_limits.T
        ok = pos_err <= self.position_tolerance and rot_err <= self.rotation_tolerance
        ok = ok and bool(np.all(q >= lo - 1e-6) and np.all(q <= hi + 1e-6))
        return IKResult(q, ok, pos_err, rot_err)

    def step(self, q_arm: np.ndarray, T_world_tcp: np.ndarray) -> np.ndarray:
        """One tracking step of ``CONTROL_DT`` from ``q_arm`` towards ``T_world_tcp``."""
        self._set_target(T_world_tcp)
        self.configuration.update(self._full(q_arm))
        v = mink.solve_ik(self.configuration, self.tasks, CONTROL_DT, "daqp", damping=1e-3, limits=self.limits)
        self.configuration.integrate_inplace(v, CONTROL_DT)
        return self.configuration.q[self.index.arm_qpos].copy()


class MotionAborted(RuntimeError):
    """A monitor stopped a motion; ``reason`` names why (e.g. ``collision``)."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


Monitor = Callable[[], str | None]
"""Called after every control tick; returns a failure reason to abort the motion, or None."""


class Executor:
    """Runs motion primitives on a work-cell ``Scene`` by writing servo references and stepping physics.

    The commanded arm configuration ``q_ref`` and gripper reference are the executor's state; the
    physical joints follow them through the position servos. ``on_tick`` (if given) is called after each
    control tick, e.g. to record the state.
    """

    def __init__(self, scene: Scene, ik: IK, on_tick: Callable[[], None] | None = None) -> None:
        self.scene = scene
        self.ik = ik
        self.robot = RobotIndex(scene.model)
        self.on_tick = on_tick
        self.substeps = round(CONTROL_DT / scene.model.opt.timestep)
        self.q_ref = READY_Q.copy()
        self.grip_ref = GRIPPER.finger_travel

    def reset(self, q_arm: np.ndarray, opening: float = GRIPPER.max_width) -> None:
        """Teleport the arm to ``q_arm`` at rest with the jaws at ``opening`` (before any physics)."""
        d, r = self.scene.data, self.robot
        d.qpos[r.arm_qpos] = q_arm
        d.qvel[r.arm_qvel] = 0.0
        d.qpos[r.finger_qpos] = opening / 2.0
        self.q_ref = np.array(q_arm, dtype=float)
        self.grip_ref = opening / 2.0
        self._write_ctrl()
        self.scene.forward()

    def tcp_pose(self) -> np.ndarray:
        """The physical TCP pose ``T_world_tcp`` now."""
        d, s = self.scene.data, self.robot.tcp_site
        return make_pose(d.site_xmat[s].reshape(3, 3), d.site_xpos[s])

    def _write_ctrl(self) -> None:
        d, r = self.scene.data, self.robot
        d.ctrl[r.arm_actuators] = self.q_ref
        d.ctrl[r.gripper_actuator] = self.grip_ref

    def _tick(self, monitor: Monitor | None) -> None:
        self._write_ctrl()
        self.scene.step(self.substeps)
        if self.on_tick is not None:
            self.on_tick()
        if monitor is not None:
            reason = monitor()
            if reason is not None:
                raise MotionAborted(reason, f"at t = {self.scene.data.time:.2f} s")

    def wait(self, duration: float, monitor: Monitor | None = None) -> None:
        for _ in range(max(1, round(duration / CONTROL_DT))):
            self._tick(monitor)

    def move_joints(self, q_goal: np.ndarray, duration: float | None = None, monitor: Monitor | None = None,
                    speed_fraction: float = 0.5) -> None:
        """Minimum-jerk joint-space move; by default as fast as ``speed_fraction`` of the joint speed limits
        allows (the peak speed of a minimum-jerk profile is 1.875 × the mean)."""
        q0 = self.q_ref.copy()
        if duration is None:
            duration = float(np.max(1.875 * np.abs(q_goal - q0) / (speed_fraction * JOINT_SPEED)))
            duration = max(duration, 0.3)
        n = max(1, round(duration / CONTROL_DT))
        for k in range(1, n + 1):
            self.q_ref = q0 + min_jerk(k / n) * (q_goal - q0)
            self._tick(monitor)

    def move_linear(self, T_goal: np.ndarray, duration: float, monitor: Monitor | None = None) -> float:
        """Straight-line TCP move from the commanded pose to ``T_goal``; returns the distance (m) left between
        the IK reference's TCP and the goal at the end (the error of the IK itself, not of the servos)."""
        T0 = self.ik.tcp_pose(self.q_ref)
        R0, p0 = T0[:3, :3], T0[:3, 3]
        slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([R0, T_goal[:3, :3]])))  # R0·exp(s·log(R0ᵀR1))
        n = max(1, round(duration / CONTROL_DT))
        for k in range(1, n + 1):
            s = min_jerk(k / n)
            target = make_pose(slerp(s).as_matrix(), p0 + s * (T_goal[:3, 3] - p0))
            self.q_ref = self.ik.step(self.q_ref, target)
            self._tick(monitor)
        err = float("inf")
        for _ in range(20):  # settle the reference onto the goal
            self.q_ref = self.ik.step(self.q_ref, T_goal)
            err = float(np.linalg.norm(self.ik.tcp_pose(self.q_ref)[:3, 3] - T_goal[:3, 3]))
            if err < 1e-3:
                break
        return err

    def set_gripper(self, opening: float, duration: float, monitor: Monitor | None = None) -> None:
        """Ramp the jaw reference to ``opening`` (m) over ``duration``; the servo's force limit caps the
        squeeze when the jaws meet an object."""
        g0, g1 = self.grip_ref, float(np.clip(opening, 0.0, GRIPPER.max_width)) / 2.0
        n = max(1, round(duration / CONTROL_DT))
        for k in range(1, n + 1):
            self.grip_ref = g0 + (k / n) * (g1 - g0)
            self._tick(monitor)

