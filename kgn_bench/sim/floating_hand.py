"""A free-floating parallel gripper, and GIGA's grasp execution with it (no arm).

**Model.** ``add_floating_hand`` adds a mocap body ``mount`` and a free body ``carrier`` welded to it (a weld,
not a mocap parent: a teleported body has no velocity, so friction could not carry a grasped object along);
the gripper of ``sim.robot.build_gripper`` hangs from the carrier at its flange, its bodies gravity
compensated. Moving the mocap target moves the hand, which follows through the weld and stops against what
it meets. The carrier's frame is the hand's: grasp-frame orientation (+x approach, z closing), origin at the
flange, so for a TCP pose ``T_world_tcp`` (a grasp pose, ``kgn_bench.grasp``) the carrier sits at
``T_world_hand = T_world_tcp · Trans(−tcp_offset, 0, 0)``. When not in use the hand is parked at
``PARK_POSITION``, beyond the camera's far plane.

**Execution** (``execute_grasp``, GIGA's ``execute_grasp`` as their code does it; the numbers are
``kgn_bench.giga``'s), for a world grasp ``T_world_grasp``:

1. the hand appears, jaws fully open, at the pre-grasp ``T_world_grasp · Trans(−PREGRASP_DISTANCE, 0, 0)``;
   a contact there is a ``collision``;
2. it moves straight to the grasp at ``APPROACH_SPEED``. At the first contact it stops where it is: with
   ``allow_contact`` (GIGA's evaluation) the grasp goes on from there, without (their data generation, where
   a grasp must be reachable without touching anything) it is a ``collision``;
3. the jaws are driven shut for ``CLOSE_TIME``; jaws that close to ``MIN_HELD_WIDTH × max_width`` or less
   closed on nothing: ``missed``;
4. it moves ``LIFT_DISTANCE`` at ``APPROACH_SPEED`` without stopping: straight up (world +z) when the
   approach is more than ``SIDE_GRASP_DEG`` from straight down, else back along its approach;
5. success: the hand touches an object and the jaws are still more than ``MIN_HELD_WIDTH × max_width`` apart;
   the object is the one the first such contact names (GIGA deletes that body). Otherwise ``dropped_lift``.

GIGA's rule counts a contact with any body; this one counts objects only (after a 10 cm lift the hand can
touch nothing else but the table, which would be a false success). GIGA has no shake and no transport.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from kgn_bench import giga
from kgn_bench.geometry import make_pose, quat_wxyz_from_matrix
from kgn_bench.gripper import GripperGeometry
from kgn_bench.sim.robot import add_floor, build_gripper, descends
from kgn_bench.sim.scene import Scene

__all__ = ["APPROACH_CHECKS", "CLOSING_CHECKS", "CONTROL_DT", "PARK_POSITION", "FloatingHand", "FloatingOutcome",
           "add_floating_cell", "add_floating_hand", "execute_grasp", "lift_pose", "precheck_grasp"]

CONTROL_DT = 0.01
"""Control period (s): the mocap target moves once per tick."""
PARK_POSITION = np.array([0.0, 0.0, 20.0])
"""Where (world, m) the hand waits between grasps: beyond the camera's 10 m far plane, above everything."""
WELD_SOLREF = (0.005, 1.0)
"""The weld's time constant and damping ratio: stiff enough that the hand lags its target by < 1 mm."""


def add_floating_hand(root, g: GripperGeometry) -> None:
    """Add the mocap ``mount``, the welded free ``carrier`` and gripper ``g`` (names ``gripper/...``) to the
    MJCF ``root``, parked at ``PARK_POSITION``."""
    root.worldbody.add("body", name="mount", mocap=True, pos=PARK_POSITION)
    carrier = root.worldbody.add("body", name="carrier", gravcomp=1, pos=PARK_POSITION)
    carrier.add("freejoint", name="carrier")
    carrier.add("inertial", pos=(0, 0, 0), mass=0.1, diaginertia=(1e-4, 1e-4, 1e-4))
    carrier.add("site", name="flange").attach(build_gripper(g))
    root.equality.add("weld", body1="mount", body2="carrier", solref=WELD_SOLREF)


def add_floating_cell(root, g: GripperGeometry) -> None:
    """The work cell without an arm: the floor and the floating hand ``g`` (no place bin: a grasped object
    leaves the scene)."""
    add_floor(root)
    add_floating_hand(root, g)


@dataclass(frozen=True)
class FloatingOutcome:
    """``reason`` None = success, else ``collision``, ``missed`` or ``dropped_lift``; ``object`` the index of
    the object the hand held at the end (success) or None; ``opening`` the jaw opening (m) at the end."""

    reason: str | None
    object: int | None
    opening: float
    detail: str = ""


class FloatingHand:
    """The floating hand of a compiled ``Scene`` built with ``add_floating_hand``; ``g`` must be the geometry
    it was built from. ``on_tick`` (if set) is called after every control tick, e.g. to record the state."""

    def __init__(self, scene: Scene, g: GripperGeometry) -> None:
        m = scene.model
        self.scene, self.g = scene, g
        self._quats: dict[bytes, np.ndarray] = {}
        self.on_tick: Callable[[], None] | None = None

        def named(kind: mujoco.mjtObj, name: str) -> int:
            i = mujoco.mj_name2id(m, kind, name)
            if i < 0:
                raise ValueError(f"the scene has no floating hand ({name!r} missing): build it with add_floating_hand")
            return i

        self.mocap = m.body_mocapid[named(mujoco.mjtObj.mjOBJ_BODY, "mount")]
        carrier = named(mujoco.mjtObj.mjOBJ_BODY, "carrier")
        self.carrier_qpos = m.jnt_qposadr[m.body_jntadr[carrier]]
        self.carrier_qvel = m.jnt_dofadr[m.body_jntadr[carrier]]
        self.finger_qpos = np.array([m.jnt_qposadr[named(mujoco.mjtObj.mjOBJ_JOINT, f"gripper/{n}")]
                                     for n in ("left_finger", "right_finger")])
        self.finger_qvel = np.array([m.jnt_dofadr[named(mujoco.mjtObj.mjOBJ_JOINT, f"gripper/{n}")]
                                     for n in ("left_finger", "right_finger")])
        self.actuator = named(mujoco.mjtObj.mjOBJ_ACTUATOR, "gripper/gripper")
        self.tcp_site = named(mujoco.mjtObj.mjOBJ_SITE, "gripper/tcp")
        self.pad_geoms = np.array([named(mujoco.mjtObj.mjOBJ_GEOM, f"gripper/{n}_pad")
                                   for n in ("left_finger", "right_finger")])
        bodies = [b for b in range(m.nbody) if descends(m, b, carrier)]
        self.geoms = np.flatnonzero(np.isin(m.geom_bodyid, bodies))
        self.is_hand = np.zeros(m.ngeom, dtype=bool)
        self.is_hand[self.geoms] = True
        self.substeps = max(1, round(CONTROL_DT / m.opt.timestep))

    # -- state --------------------------------------------------------------------------------------
    def opening(self) -> float:
        """The jaw opening now (m): the sum of the two finger slides."""
        return float(self.scene.data.qpos[self.finger_qpos].sum())

    def tcp_pose(self) -> np.ndarray:
        """The TCP's world pose ``T_world_tcp`` now."""
        d = self.scene.data
        return make_pose(d.site_xmat[self.tcp_site].reshape(3, 3), d.site_xpos[self.tcp_site])

    def _hand_pose(self, T_world_tcp: np.ndarray) -> np.ndarray:
        return T_world_tcp @ make_pose(t=np.array([-self.g.tcp_offset, 0.0, 0.0]))

    def _quat(self, R: np.ndarray) -> np.ndarray:
        """``quat_wxyz_from_matrix(R)``, remembered for the last few matrices: a straight move and the
        pre-check's poses keep one orientation over hundreds of targets, and the conversion was a third of
        the data generator's time. The same bits as computing it each time."""
        key = np.ascontiguousarray(R, dtype=float).tobytes()
        q = self._quats.get(key)
        if q is None:
            if len(self._quats) >= 8:
                self._quats.pop(next(iter(self._quats)))
            q = self._quats[key] = quat_wxyz_from_matrix(R)
        return q

    def _set_target(self, T_world_tcp: np.ndarray) -> None:
        T = self._hand_pose(T_world_tcp)
        self.scene.data.mocap_pos[self.mocap] = T[:3, 3]
        self.scene.data.mocap_quat[self.mocap] = self._quat(T[:3, :3])

    def teleport(self, T_world_tcp: np.ndarray, opening: float | None = None) -> None:
        """Put the hand (and its target) at ``T_world_tcp``, at rest, jaws at ``opening`` (default: fully
        open), and recompute the kinematics and contacts."""
        d = self.scene.data
        T = self._hand_pose(T_world_tcp)
        self._set_target(T_world_tcp)
        a, v = self.carrier_qpos, self.carrier_qvel
        d.qpos[a : a + 3] = T[:3, 3]
        d.qpos[a + 3 : a + 7] = self._quat(T[:3, :3])
        d.qvel[v : v + 6] = 0.0
        half = (self.g.max_width if opening is None else opening) / 2.0
        d.qpos[self.finger_qpos] = half
        d.qvel[self.finger_qvel] = 0.0
        d.ctrl[self.actuator] = half
        self.scene.forward()

    def park(self) -> None:
        """Send the hand to ``PARK_POSITION``, jaws open."""
        self.teleport(make_pose(t=PARK_POSITION))

    def contacts(self) -> list[tuple[int, int]]:
        """``(hand geom, other geom)`` of every contact between the hand and anything else, in MuJoCo's order."""
        d = self.scene.data
        pairs = d.contact.geom[: d.ncon]
        first_is_hand = self.is_hand[pairs[:, 0]]
        mixed = first_is_hand != self.is_hand[pairs[:, 1]]
        hand = np.where(first_is_hand, pairs[:, 0], pairs[:, 1])[mixed]
        other = np.where(first_is_hand, pairs[:, 1], pairs[:, 0])[mixed]
        return [(int(a), int(b)) for a, b in zip(hand, other)]

    def touched_objects(self) -> list[int]:
        """Indices of the objects the hand touches, in the order of their first contact."""
        out: list[int] = []
        for _, other in self.contacts():
            label = int(self.scene.geom_label[other])
            if label > 0 and label - 1 not in out:
                out.append(label - 1)
        return out

    # -- motion ---------------------------------------------------------------------------------------
    def _tick(self) -> None:
        self.scene.step(self.substeps)
        if self.on_tick is not None:
            self.on_tick()

    def wait(self, duration: float) -> None:
        for _ in range(max(1, round(duration / CONTROL_DT))):
            self._tick()

    def move_linear(self, T_goal: np.ndarray, speed: float, stop_on_contact: bool = False) -> bool:
        """Move the target straight from the hand's TCP to ``T_goal`` (same orientation; world frame) at
        ``speed`` m/s. With ``stop_on_contact``, stop at the first tick that ends with the hand touching
        anything, leaving the target where the hand is; returns whether that happened."""
        start = self.tcp_pose()
        p0, p1 = start[:3, 3], T_goal[:3, 3]
        n = max(1, int(np.ceil(np.linalg.norm(p1 - p0) / (speed * CONTROL_DT))))
        for k in range(1, n + 1):
            target = T_goal.copy()
            target[:3, 3] = p0 + (k / n) * (p1 - p0)
            self._set_target(target)
            self._tick()
            if stop_on_contact and self.contacts():
                self._set_target(self.tcp_pose())
                return True
        return False

    def close(self, duration: float) -> None:
        """Drive the jaws shut: the servo's reference ramps to 0 over the first half of ``duration`` and
        holds; its force limit (``GripperGeometry.grip_force``) sets the squeeze."""
        d = self.scene.data
        n = max(1, round(duration / CONTROL_DT))
        start = float(d.ctrl[self.actuator])
        for k in range(1, n + 1):
            d.ctrl[self.actuator] = start * max(0.0, 1.0 - 2.0 * k / n)
            self._tick()


def lift_pose(T_world_grasp: np.ndarray) -> np.ndarray:
    """Where the hand goes after closing (world TCP pose): ``LIFT_DISTANCE`` straight up when the approach
    (+x of the grasp frame) is more than ``SIDE_GRASP_DEG`` from straight down, else back along the approach."""
    approach = T_world_grasp[:3, 0]
    out = T_world_grasp.copy()
    if approach @ np.array([0.0, 0.0, -1.0]) < np.cos(np.deg2rad(giga.SIDE_GRASP_DEG)):
        out[2, 3] += giga.LIFT_DISTANCE
    else:
        out[:3, 3] -= giga.LIFT_DISTANCE * approach
    return out


def execute_grasp(hand: FloatingHand, T_world_grasp: np.ndarray, allow_contact: bool = True) -> FloatingOutcome:
    """Execute one grasp with the floating hand GIGA's way (module doc) and park the hand. ``PhysicsError``
    propagates (the caller decides what a blow-up means)."""
    min_width = giga.MIN_HELD_WIDTH * hand.g.max_width
    pre = T_world_grasp @ make_pose(t=np.array([-giga.PREGRASP_DISTANCE, 0.0, 0.0]))
    try:
        hand.teleport(pre)
        touching = hand.contacts()
        if touching:
            return FloatingOutcome("collision", None, hand.opening(), f"{_names(hand, touching[0])} at the pre-grasp")
        stopped = hand.move_linear(T_world_grasp, giga.APPROACH_SPEED, stop_on_contact=True)
        if stopped and not allow_contact:
            return FloatingOutcome("collision", None, hand.opening(),
                                   f"{_names(hand, hand.contacts()[0])} on the approach")
        hand.close(giga.CLOSE_TIME)
        if hand.opening() <= min_width:
            return FloatingOutcome("missed", None, hand.opening(), f"jaws closed to {hand.opening() * 1e3:.1f} mm")
        hand.move_linear(lift_pose(T_world_grasp), giga.APPROACH_SPEED)
        held = hand.touched_objects()
        width = hand.opening()
        if held and width > min_width:
            return FloatingOutcome(None, held[0], width)
        return FloatingOutcome("dropped_lift", None, width,
                               f"jaws at {width * 1e3:.1f} mm, {'touching' if held else 'not touching'} an object")
    finally:
        if np.all(np.isfinite(hand.scene.data.qpos)):
            hand.park()


APPROACH_CHECKS = 10
"""Poses the pre-check tests on the straight approach (5 mm apart over GIGA's 5 cm)."""
CLOSING_CHECKS = 8
"""Openings the pre-check tests between fully open and the held-width floor."""


def precheck_grasp(hand: FloatingHand, T_world_grasp: np.ndarray) -> str | None:
    """Kinematic test of a grasp that ``execute_grasp(..., allow_contact=False)`` would fail, without dynamics:
    ``"pre-grasp"`` (the open hand touches something at the pre-grasp: execution's step 1, the same test),
    ``"approach"`` (it touches something at one of ``APPROACH_CHECKS`` poses evenly spaced on the way in: the
    contact that step 2 stops at), ``"empty"`` (at the grasp, the jaws set at ``CLOSING_CHECKS`` openings from
    fully open down to the held-width floor touch nothing: they would close on nothing, a ``missed``), or None
    (execute it). Nothing moves: the hand is teleported, contacts recomputed, and parked after. A grasp it
    rejects is one execution fails except where the dynamics differ from the kinematics (the hand lagging its
    target, a finger's sag); ``results/calibration`` measures how often (0.12 % of rejections)."""
    pre = T_world_grasp @ make_pose(t=np.array([-giga.PREGRASP_DISTANCE, 0.0, 0.0]))
    try:
        hand.teleport(pre)
        if hand.contacts():
            return "pre-grasp"
        for k in range(1, APPROACH_CHECKS + 1):
            pose = T_world_grasp.copy()
            pose[:3, 3] = pre[:3, 3] + (k / APPROACH_CHECKS) * (T_world_grasp[:3, 3] - pre[:3, 3])
            hand.teleport(pose)
            if hand.contacts():
                return "approach"
        floor = giga.MIN_HELD_WIDTH * hand.g.max_width
        for width in np.linspace(hand.g.max_width, floor, CLOSING_CHECKS + 1)[1:]:
            hand.teleport(T_world_grasp, opening=float(width))
            if hand.contacts():
                return None
        return "empty"
    finally:
        hand.park()


def _names(hand: FloatingHand, pair: tuple[int, int]) -> str:
    m = hand.scene.model
    return f"{m.geom(pair[0]).name} touched {m.geom(pair[1]).name}"
