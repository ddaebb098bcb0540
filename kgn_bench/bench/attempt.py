"""One grasp attempt in the work cell: pre-grasp, straight approach, close, lift, carry to the bin,
release; the outcome and its failure reason.

Failure reasons: ``collision`` (before closing, the arm or palm touched anything, or a finger
touched the table, bin or floor), ``missed`` (no object between both fingers after closing),
``dropped_lift`` (held after closing but, after the lift, no longer held or the object point that was at
the TCP when the jaws closed rose less than ``min_lift``: slip at the grasp, while an object that only
swings about the grasp point still counts as lifted),
``dropped_transport`` (lost on the way or released outside the bin), ``physics_error``. Success: the
object is inside the bin after release, also when it slipped from the jaws just before (over the bin there
is nowhere else to fall; the attempt's detail says so). All poses are world frame.

With a floating hand (``execution.hand = "floating"``) an attempt is GIGA's instead (``execute_floating``,
``sim.floating_hand.execute_grasp``): no arm, no transport; success is an object still touching the hand, jaws
apart, after the lift; failures are ``collision`` (at the pre-grasp), ``missed`` and ``dropped_lift``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from kgn_bench.config import ExecutionConfig
from kgn_bench.gripper import GRIPPER
from kgn_bench.sim import floating_hand
from kgn_bench.sim.control import IK, Executor, MotionAborted
from kgn_bench.sim.floating_hand import FloatingHand
from kgn_bench.sim.robot import BIN, PARK_Q, READY_Q
from kgn_bench.sim.scene import PhysicsError, Scene

from .selector import Selection

__all__ = ["FAILURE_REASONS", "NOT_EXECUTED", "AttemptResult", "bin_drop_q", "execute_floating", "execute_grasp",
           "held_object"]

FAILURE_REASONS = ("no_candidate", "unreachable", "missed", "dropped_lift", "dropped_transport", "collision",
                   "physics_error", "detector_error")
NOT_EXECUTED = ("no_candidate", "unreachable")
"""Outcomes where nothing was executed: the selector passed no candidate (or none the arm reaches). They end
a pile or packed round and, as in VGN/GIGA, are not grasp attempts there."""
BIN_DROP_HEIGHT = 0.30


@dataclass
class AttemptResult:
    """``reason`` None = success; ``object`` = index of the object that was held (or None)."""

    reason: str | None
    object: int | None = None
    detail: str = ""


@cache
def bin_drop_q() -> np.ndarray:
    """Arm configuration with the TCP ``BIN_DROP_HEIGHT`` above the bin centre, pointing down."""
    ik = IK()
    T = ik.tcp_pose(READY_Q)
    T[:3, 3] = (*BIN.centre, BIN_DROP_HEIGHT)
    result = ik.solve(T)
    if not result.ok:
        raise RuntimeError(f"the place bin is out of reach (IK error {result.position_error:.3f} m)")
    return result.q


def _contact_pairs(scene: Scene) -> np.ndarray:
    """Geom id pairs (K, 2) of the contacts MuJoCo found at the last step."""
    d = scene.data
    return d.contact.geom[: d.ncon].copy() if d.ncon else np.zeros((0, 2), dtype=int)


def held_object(scene: Scene, executor: Executor) -> int | None:
    """The object touching both fingers' pads, if any (the lowest index when several)."""
    pairs = _contact_pairs(scene)
    touching = []
    for pad in executor.robot.pad_geoms:
        other = np.concatenate([pairs[pairs[:, 0] == pad, 1], pairs[pairs[:, 1] == pad, 0]])
        labels = scene.geom_label[other]
        touching.append(set(labels[labels > 0].tolist()))
    both = sorted(touching[0] & touching[1])
    return both[0] - 1 if both else None


class _CollisionMonitor:
    """Before closing: the arm or palm touching anything, or a finger touching the table, bin or floor,
    is a collision (fingers may touch objects). ``detail`` names the first offending pair."""

    def __init__(self, scene: Scene, executor: Executor) -> None:
        self.scene = scene
        self.is_robot = np.zeros(scene.model.ngeom, dtype=bool)
        self.is_robot[executor.robot.geoms] = True
        self.is_pad = np.zeros(scene.model.ngeom, dtype=bool)
        self.is_pad[executor.robot.pad_geoms] = True
        self.detail = ""

    def __call__(self) -> str | None:
        pairs = _contact_pairs(self.scene)
        r0, r1 = self.is_robot[pairs[:, 0]], self.is_robot[pairs[:, 1]]
        mixed = r0 ^ r1
        robot = np.where(r0, pairs[:, 0], pairs[:, 1])[mixed]
        other = np.where(r0, pairs[:, 1], pairs[:, 0])[mixed]
        bad = np.flatnonzero(~self.is_pad[robot] | (self.scene.geom_label[other] == 0))
        if len(bad) == 0:
            return None
        m, k = self.scene.model, bad[0]
        self.detail = f"{m.geom(int(robot[k])).name} touched {m.geom(int(other[k])).name}"
        return "collision"


def _retreat(executor: Executor, sel: Selection, cfg: ExecutionConfig) -> None:
    """After a failed grasp: open, back off along the approach, park. Errors here do not change the outcome."""
    try:
        executor.set_gripper(sel.width, 0.2)
        executor.move_linear(sel.pregrasp, cfg.approach_time)
        executor.move_joints(PARK_Q)
    except (MotionAborted, PhysicsError):
        pass


def execute_grasp(scene: Scene, executor: Executor, sel: Selection, cfg: ExecutionConfig,
                  park: bool = True) -> AttemptResult:
    """Execute a selected grasp from the park configuration and report the outcome."""
    assert sel.grasp is not None and sel.q_pregrasp is not None
    monitor = _CollisionMonitor(scene, executor)
    try:
        try:
            phase = "opening"
            executor.set_gripper(sel.width, 0.2)
            phase = "moving to pre-grasp"
            executor.move_joints(sel.q_pregrasp, monitor=monitor)
            phase = "approaching"
            executor.move_linear(sel.grasp, cfg.approach_time, monitor=monitor)
            phase = "settling before closing"
            executor.wait(0.2, monitor=monitor)
        except MotionAborted as e:
            _retreat(executor, sel, cfg)
            return AttemptResult(e.reason, detail=f"{monitor.detail} while {phase} ({e})")
        executor.set_gripper(0.0, 0.4)
        executor.wait(0.25)
        held = held_object(scene, executor)
        if held is None:
            detail = f"jaws closed to {executor.robot.opening(scene.data) * 1e3:.1f} mm"
            _retreat(executor, sel, cfg)
            return AttemptResult("missed", detail=detail)
        T0 = scene.object_pose(held)
        grip_point = np.linalg.solve(T0, np.append(scene.data.site_xpos[executor.robot.tcp_site], 1.0))
        lift = executor.ik.tcp_pose(executor.q_ref)
        lift[2, 3] += cfg.lift_height
        executor.move_linear(lift, 0.8)
        executor.wait(cfg.settle_time)
        T1 = scene.object_pose(held)
        rise = float((T1 @ grip_point)[2] - (T0 @ grip_point)[2])
        if held_object(scene, executor) != held or rise < cfg.min_lift:
            executor.set_gripper(GRIPPER.max_width, 0.2)
            if park:
                executor.move_joints(PARK_Q)
            return AttemptResult("dropped_lift", held, f"grasp point rose {rise * 1e3:.0f} mm")
        executor.move_joints(bin_drop_q())
        carried = held_object(scene, executor) == held
        executor.set_gripper(GRIPPER.max_width, 0.3)
        executor.wait(0.6)
        in_bin = BIN.contains(scene.object_position(held))
        if park:
            executor.move_joints(PARK_Q)
        if not in_bin:
            where = np.round(scene.object_position(held), 3).tolist()
            return AttemptResult("dropped_transport", held, f"object ended at {where}")
        return AttemptResult(None, held, "" if carried else "slipped from the jaws over the bin, fell in")
    except PhysicsError as e:
        return AttemptResult("physics_error", detail=str(e))


def execute_floating(hand: FloatingHand, sel: Selection) -> AttemptResult:
    """Execute a selected grasp with the floating hand, GIGA's way (contact on the approach allowed, as in
    their evaluation), and report the outcome; the hand is parked afterwards."""
    assert sel.grasp is not None
    try:
        out = floating_hand.execute_grasp(hand, sel.grasp, allow_contact=True)
    except PhysicsError as e:
        return AttemptResult("physics_error", detail=str(e))
    return AttemptResult(out.reason, out.object, out.detail)
