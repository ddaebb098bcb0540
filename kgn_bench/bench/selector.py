"""Grasp selection (DESIGN §7): rank candidates by score, then keep the first that passes the gripper prior.

Score: ``s = c − λ·RE`` (``confidence_minus_error``, the default) or the paper's printed ``s = c + RE``
(``paper_literal``); a missing reprojection error (NaN) counts as 0. Then, in this order, each rejection
counted:

1. ``width``: 0 < w ≤ the gripper's maximum opening;
2. ``collision``: the gripper's boxes (fingers at the candidate's width, palm, wrist), swept from the
   pre-grasp back-off to the grasp, contain fewer than ``collision_points`` observed points and stay
   ``table_clearance`` above the table top;
3. ``enclosure``: the closing region between the fingers holds at least ``enclosed_points`` observed points;
4. ``ik``: IK reaches the pre-grasp and then the grasp within joint limits.

The observed points come from the depth image (world frame), never from the simulator. Poses are world
frame ``T_world_grasp``. Each candidate is tried in both of its 180°-symmetric forms (the one closer to the
arm's ready wrist first). The executed grasp is pushed ``grasp_depth`` further along its approach when the
fingertips have room above the table.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kgn_bench.config import ExecutionConfig, SelectorConfig
from kgn_bench.grasp import flip_180
from kgn_bench.gripper import GRIPPER, GripperBox, box_corners
from kgn_bench.sim.control import IK
from kgn_bench.sim.robot import READY_Q

__all__ = ["REJECTIONS", "Selection", "score_candidates", "select_grasp"]

REJECTIONS = ("width", "collision", "enclosure", "ik")


@dataclass
class Selection:
    """The chosen grasp (world frame) with its pre-grasp and IK solutions, or ``index = None``.

    ``rejected`` counts candidates rejected by each check; ``scores`` are all candidates' scores.
    """

    index: int | None
    scores: np.ndarray
    rejected: dict[str, int] = field(default_factory=lambda: dict.fromkeys(REJECTIONS, 0))
    grasp: np.ndarray | None = None
    pregrasp: np.ndarray | None = None
    width: float = 0.0
    q_pregrasp: np.ndarray | None = None
    q_grasp: np.ndarray | None = None

    @property
    def reason(self) -> str | None:
        """Why nothing was selected: ``no_candidate`` or ``unreachable`` (IK was the last obstacle)."""
        if self.index is not None:
            return None
        return "unreachable" if self.rejected["ik"] > 0 else "no_candidate"


def score_candidates(confidences: np.ndarray, errors: np.ndarray, cfg: SelectorConfig) -> np.ndarray:
    re = np.nan_to_num(errors, nan=0.0)
    if cfg.score == "paper_literal":
        return confidences + re
    return confidences - cfg.reprojection_weight * re


def _swept(box: GripperBox, back: float) -> GripperBox:
    """The volume a grasp-frame box sweeps moving from ``back`` m behind along −x to its place."""
    half = box.half + np.array([back / 2.0, 0.0, 0.0])
    return GripperBox(box.name, box.centre - np.array([back / 2.0, 0.0, 0.0]), half)


def _count_inside(points_g: np.ndarray, box: GripperBox) -> int:
    return int(np.count_nonzero(np.all(np.abs(points_g - box.centre) < box.half, axis=1)))


def _grasp_depth(pose: np.ndarray, width: float, depth: float, clearance: float) -> float:
    """How far (≤ ``depth``) the grasp can move along its approach with the fingers above the table."""
    az = pose[2, 0]
    if az >= -1e-6:
        return depth
    low = min(box_corners(GRIPPER.finger_box(s, width), pose[None])[0, :, 2].min() for s in (1, -1))
    return float(np.clip((low - clearance) / -az, 0.0, depth))


def select_grasp(poses: np.ndarray, widths: np.ndarray, confidences: np.ndarray, errors: np.ndarray,
                 points: np.ndarray, ik: IK, cfg: SelectorConfig, execution: ExecutionConfig) -> Selection:
    """Pick the best feasible candidate among world-frame ``poses`` given observed world ``points``."""
    scores = score_candidates(confidences, errors, cfg)
    sel = Selection(index=None, scores=scores)
    order = np.argsort(-scores, kind="stable")[: cfg.max_candidates]
    back = execution.pregrasp_distance
    ready_closing = ik.tcp_pose(READY_Q)[:3, 2]
    for k in order:
        w = float(widths[k])
        if not (0.0 < w <= GRIPPER.max_width):
            sel.rejected["width"] += 1
            continue
        open_w = min(w + 0.01, GRIPPER.max_width)
        pose = poses[k]
        depth = _grasp_depth(pose, open_w, execution.grasp_depth, cfg.table_clearance)
        pose = pose.copy()
        pose[:3, 3] += depth * pose[:3, 0]
        boxes = [_swept(b, back) for b in GRIPPER.boxes(open_w)]
        corners = np.concatenate([box_corners(b, pose[None])[0] for b in boxes])
        near = points[np.linalg.norm(points - pose[:3, 3], axis=1) < 0.35]
        local = (near - pose[:3, 3]) @ pose[:3, :3]
        hits = sum(_count_inside(local, b) for b in boxes)
        if corners[:, 2].min() < cfg.table_clearance - 1e-6 or hits >= cfg.collision_points:
            sel.rejected["collision"] += 1
            continue
        if _count_inside(local, GRIPPER.closing_region(w)) < cfg.enclosed_points:
            sel.rejected["enclosure"] += 1
            continue
        flipped = flip_180(pose[None])[0]
        forms = (pose, flipped) if pose[:3, 2] @ ready_closing >= 0 else (flipped, pose)
        for form in forms:
            pre = form.copy()
            pre[:3, 3] -= back * form[:3, 0]
            r_pre = ik.solve(pre)
            if not r_pre.ok:
                continue
            r_grasp = ik.solve(form, r_pre.q)
            if r_grasp.ok:
                sel.index = int(k)
                sel.grasp, sel.pregrasp, sel.width = form, pre, open_w
                sel.q_pregrasp, sel.q_grasp = r_pre.q, r_grasp.q
                return sel
        sel.rejected["ik"] += 1
    return sel
