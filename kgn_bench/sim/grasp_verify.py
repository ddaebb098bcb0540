"""Physics check of grasp candidates: the object alone with a free-floating copy of the benchmark's gripper.

For each grasp ``T_obj_grasp`` (object frame; the object starts at the world origin, far above the table):

1. the hand (``sim.robot.build_gripper``, the same MJCF the arm carries) rides on the free body welded to a
   mocap target of ``sim.floating_hand.add_floating_hand``, placed so that its TCP is where the executor
   closes, ``depth`` (1 cm) past the grasp along its approach:
   ``T_world_hand = T_obj_grasp · Trans(depth − tcp_offset, 0, 0)``; the jaws start at the executor's opening
   ``GRIPPER.opening(width)``;
2. a grasp whose open gripper already overlaps the object by more than ``max_start_penetration`` fails: the
   arm reaches a grasp from its pre-grasp, so no real gripper gets there (and MuJoCo would push the overlap
   apart into a wedge that holds);
3. **close** with gravity off, the servo commanded shut under its real force limit (``GRIPPER.grip_force``),
   for ``close_s``; the grasp fails if the jaws close on nothing (opening < ``min_opening``);
4. **hold**: gravity on, pulling along the grasp's approach axis ``+x`` (out of the fingers, as gravity pulls an
   object lifted from a top-down grasp), for ``hold_s``;
5. **shake**: the hand translates ``shake_m`` back and forth along each grasp axis and turns ``shake_deg`` back
   and forth about each, one ``shake_period_s`` cycle per axis, with gravity on.

A grasp holds when the object's displacement relative to the hand stays under ``max_slip_m`` (the object
frame's origin in the hand frame, from after closing to the end) and the jaws are still apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from kgn_bench.execution import GRASP_DEPTH as APPROACH_DEPTH
from kgn_bench.geometry import make_pose, quat_wxyz_from_matrix, quats_wxyz_from_matrices
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.base import Shape
from kgn_bench.sim.floating_hand import add_floating_hand
from kgn_bench.sim.scene import PhysicsError, SceneObject, build_mjcf

__all__ = ["ShakeTest", "verify_grasps"]

_START = np.array([0.0, 0.0, 1.0])
"""Where the object starts: 1 m above the table top, out of reach of the table."""


@dataclass(frozen=True)
class ShakeTest:
    """The timings and thresholds of the check (seconds, metres, degrees)."""

    close_s: float = 0.4
    hold_s: float = 0.3
    shake_m: float = 0.02
    shake_deg: float = 15.0
    shake_period_s: float = 0.3
    min_opening: float = 0.002
    max_slip_m: float = 0.015
    max_start_penetration: float = 0.001
    depth: float = APPROACH_DEPTH
    """How far past the grasp origin the hand closes, as the executor does (``ExecutionConfig.grasp_depth``)."""


class _Rig:
    """The compiled model: object ``object_0`` on a free joint, the gripper under mocap body ``mount``."""

    def __init__(self, shape: Shape) -> None:
        root = build_mjcf([SceneObject(shape, (0.6, 0.6, 0.6), make_pose(t=_START))])
        add_floating_hand(root, GRIPPER)
        self.model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
        self.data = mujoco.MjData(self.model)
        m = self.model
        body = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "object_0")
        self.obj_qpos = m.jnt_qposadr[m.body_jntadr[body]]
        self.obj_body = body
        self.mocap = m.body_mocapid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "mount")]
        carrier = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "carrier")
        self.carrier_qpos = m.jnt_qposadr[m.body_jntadr[carrier]]
        self.fingers = np.array([m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"gripper/{n}")]
                                 for n in ("left_finger", "right_finger")])
        self.actuator = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, "gripper/gripper")
        self.hand = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "gripper/hand")
        self.object_geoms = set(np.flatnonzero(m.geom_bodyid == body).tolist())

    def start_penetration(self) -> float:
        """The deepest overlap (m, ≥ 0) between the object and anything else, after ``mj_forward``."""
        d = self.data
        depth = 0.0
        for c in d.contact[: d.ncon]:
            if (c.geom1 in self.object_geoms) != (c.geom2 in self.object_geoms):
                depth = max(depth, -float(c.dist))
        return depth

    def set_hand(self, T_world_hand: np.ndarray, teleport: bool = False) -> None:
        """Move the mocap target of the hand (the weld pulls the hand after it); ``teleport`` puts the hand
        there too, at rest."""
        q = quat_wxyz_from_matrix(T_world_hand[:3, :3])
        self.data.mocap_pos[self.mocap] = T_world_hand[:3, 3]
        self.data.mocap_quat[self.mocap] = q
        if teleport:
            a = self.carrier_qpos
            self.data.qpos[a : a + 3] = T_world_hand[:3, 3]
            self.data.qpos[a + 3 : a + 7] = q

    def follow(self, T_world_hands: np.ndarray) -> None:
        """Step once per target of ``T_world_hands`` (K, 4, 4), the mocap target moved there before each step
        (as ``set_hand`` then ``step(1)``, the quaternions converted in one batch)."""
        quats = quats_wxyz_from_matrices(T_world_hands[:, :3, :3])
        for T, q in zip(T_world_hands, quats):
            self.data.mocap_pos[self.mocap] = T[:3, 3]
            self.data.mocap_quat[self.mocap] = q
            self.step(1)

    def object_in_hand(self) -> np.ndarray:
        """The object origin in the hand frame (m)."""
        R = self.data.xmat[self.hand].reshape(3, 3)
        return R.T @ (self.data.xpos[self.obj_body] - self.data.xpos[self.hand])

    def step(self, n: int) -> None:
        try:
            mujoco.mj_step(self.model, self.data, nstep=n)
        except mujoco.FatalError as e:
            raise PhysicsError(f"grasp check: MuJoCo fatal error ({e})") from None


def _shake_rotations(test: ShakeTest, n_cycle: int) -> np.ndarray:
    """(3·n_cycle, 3, 3): the shake's turns about the grasp's x, y and z axes in turn, one sine cycle of
    amplitude ``shake_deg`` each, sampled at the end of each of ``n_cycle`` steps."""
    phase = np.sin(2.0 * np.pi * np.arange(1, n_cycle + 1) / n_cycle)
    rotvecs = np.zeros((3 * n_cycle, 3))
    for axis in range(3):
        rotvecs[axis * n_cycle : (axis + 1) * n_cycle, axis] = np.deg2rad(test.shake_deg) * phase
    return Rotation.from_rotvec(rotvecs).as_matrix()


def _shake_targets(T_grasp: np.ndarray, test: ShakeTest, turns: np.ndarray) -> np.ndarray:
    """(6·n_cycle, 4, 4): the hand's targets ``T_world_hand`` through the shake of ``T_grasp`` (world frame):
    ``shake_m`` along the grasp's x, y, z in turn, then the ``turns`` (``_shake_rotations``) about them."""
    n_cycle = len(turns) // 3
    phase = np.sin(2.0 * np.pi * np.arange(1, n_cycle + 1) / n_cycle)
    back = make_pose(t=np.array([-GRIPPER.tcp_offset, 0.0, 0.0]))
    targets = []
    for axis in range(3):
        for s in phase:
            offset = np.zeros(3)
            offset[axis] = test.shake_m * s
            T = T_grasp.copy()
            T[:3, 3] += T_grasp[:3, :3] @ offset
            targets.append(T @ back)
    for turn in turns:
        T = T_grasp.copy()
        T[:3, :3] = T_grasp[:3, :3] @ turn
        targets.append(T @ back)
    return np.array(targets)


def _check_one(rig: _Rig, T_obj_grasp: np.ndarray, width: float, test: ShakeTest, turns: np.ndarray) -> bool:
    m, d = rig.model, rig.data
    mujoco.mj_resetData(m, d)
    d.qpos[rig.obj_qpos : rig.obj_qpos + 3] = _START
    d.qpos[rig.obj_qpos + 3 : rig.obj_qpos + 7] = (1.0, 0.0, 0.0, 0.0)
    T_grasp = make_pose(t=_START) @ T_obj_grasp @ make_pose(t=np.array([test.depth, 0.0, 0.0]))
    T_hand = T_grasp @ make_pose(t=np.array([-GRIPPER.tcp_offset, 0.0, 0.0]))
    rig.set_hand(T_hand, teleport=True)
    half = float(GRIPPER.opening(width)) / 2.0
    d.qpos[rig.fingers] = half
    d.ctrl[rig.actuator] = half
    m.opt.gravity[:] = 0.0
    mujoco.mj_forward(m, d)
    if rig.start_penetration() > test.max_start_penetration:
        return False
    dt = m.opt.timestep
    # close: ramp the servo shut over half the closing time, then let it squeeze
    n_close = max(1, int(test.close_s / dt))
    for k in range(n_close):
        d.ctrl[rig.actuator] = half * max(0.0, 1.0 - 2.0 * (k + 1) / n_close)
        rig.step(1)
    if d.qpos[rig.fingers].sum() < test.min_opening:
        return False
    ref = rig.object_in_hand()
    m.opt.gravity[:] = 9.81 * T_grasp[:3, 0]
    rig.step(max(1, int(test.hold_s / dt)))
    rig.follow(_shake_targets(T_grasp, test, turns))
    if not (np.all(np.isfinite(d.qpos)) and d.qpos[rig.fingers].sum() >= test.min_opening):
        return False
    return bool(np.linalg.norm(rig.object_in_hand() - ref) < test.max_slip_m)


def verify_grasps(shape: Shape, poses: np.ndarray, widths: np.ndarray, test: ShakeTest = ShakeTest()) -> np.ndarray:
    """(N,) bool: which grasps ``poses`` (N, 4, 4, object frame) with ``widths`` (N,) hold ``shape`` through the
    close-hold-shake check (module doc). A grasp whose simulation faults counts as not holding."""
    rig = _Rig(shape)
    turns = _shake_rotations(test, max(2, int(test.shake_period_s / rig.model.opt.timestep)))
    held = np.zeros(len(poses), dtype=bool)
    for i, (T, w) in enumerate(zip(poses, widths)):
        try:
            held[i] = _check_one(rig, T, float(w), test, turns)
        except PhysicsError:
            held[i] = False
    return held

