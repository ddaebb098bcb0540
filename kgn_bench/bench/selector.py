"""Grasp selection (DESIGN §7): rank candidates by score, then keep the first that passes the gripper prior.

Score: ``s = c − λ·RE`` (``confidence_minus_error``, the default) or the paper's printed ``s = c + RE``
(``paper_literal``); a missing reprojection error (NaN) counts as 0. Then, in this order, each rejection
counted:

1. ``width``: 0 < w ≤ the gripper's maximum opening;
2. ``collision``: the gripper's boxes (fingers at the candidate's width, palm, wrist), swept from the
   pre-grasp back-off to the grasp, contain fewer than ``collision_points`` observed points and stay
   ``table_clearance`` above the table top;
3. ``occluded``: the palm and wrist, swept the same way, stay out of space the camera cannot see: a
   sample point of them lying more than ``shadow_margin`` behind the observed surface at its pixel
   (hidden behind an object) may be inside an unseen part of that object. Only the palm and wrist are
   checked: the fingers reach past the target into its own shadow by design, the palm stays above or
   behind it. Needs the depth image (``DepthView``); skipped without one;
4. ``enclosure``: the closing region between the fingers holds at least ``enclosed_points`` observed points;
5. ``ik``: IK reaches the pre-grasp and then the grasp within joint limits.

Before these, ``repeat``: a candidate within ``retry_distance`` and ``retry_angle_deg`` (either symmetric
form) of a grasp that already failed in this trial (``failed``, world poses as executed)
is skipped: a deterministic detector would otherwise retry the same failing grasp until the consecutive
failure limit ends the scene.

The observed points come from the depth image (world frame), never from the simulator. Poses are world
frame ``T_world_grasp``. Each candidate is tried in both of its 180°-symmetric forms (the one closer to the
arm's ready wrist first). The executed grasp is pushed ``grasp_depth`` further along its approach when the
fingertips have room above the table.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kgn_bench.config import ExecutionConfig, SelectorConfig
from kgn_bench.grasp import flip_180, grasp_rotation_error
from kgn_bench.gripper import GRIPPER, GripperBox, box_corners
from kgn_bench.sim.control import IK
from kgn_bench.sim.robot import READY_Q

__all__ = ["REJECTIONS", "DepthView", "Selection", "near_failed", "score_candidates", "select_grasp"]

REJECTIONS = ("repeat", "width", "collision", "occluded", "enclosure", "ik")


@dataclass(frozen=True)
class DepthView:
    """What the camera saw: planar ``depth`` (H, W) metres (0 = no return), intrinsics ``K``, and
    ``camera_pose`` = ``T_world_cam`` (OpenCV axes)."""

    depth: np.ndarray
    K: np.ndarray
    camera_pose: np.ndarray

    def hidden(self, points_world: np.ndarray, margin: float) -> np.ndarray:
        """(N,) bool: the point projects into the image onto a measured pixel and lies more than
        ``margin`` metres behind the surface seen there (z_cam > depth + margin). Points outside the
        image, in front of the camera plane or on pixels with no return count as not hidden."""
        T = np.linalg.inv(self.camera_pose)
        p = points_world @ T[:3, :3].T + T[:3, 3]
        z = p[:, 2]
        out = np.zeros(len(p), dtype=bool)
        front = z > 1e-6
        uv = (p[front, :2] / z[front, None]) @ self.K[:2, :2].T + self.K[:2, 2]
        u, v = np.rint(uv[:, 0]).astype(int), np.rint(uv[:, 1]).astype(int)
        h, w = self.depth.shape
        inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
        idx = np.flatnonzero(front)[inside]
        seen = self.depth[v[inside], u[inside]]
        out[idx] = (seen > 0) & (z[idx] > seen + margin)
        return out


def _box_samples(box: GripperBox, n: int = 4) -> np.ndarray:
    """An n × n × n grid of points filling a grasp-frame box (corners included), (n³, 3)."""
    g = np.linspace(-1.0, 1.0, n)
    unit = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    return box.centre + unit * box.half


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


def near_failed(poses: np.ndarray, failed: np.ndarray, distance: float, angle: float) -> np.ndarray:
    """(N,) bool: pose k lies within ``distance`` (m) and ``angle`` (rad, either 180° form) of a failed pose.

    Translations are compared at the grasp origins; the executed grasps in ``failed`` (K, 4, 4) were
    pushed along their approach by at most ``grasp_depth``, which ``distance`` is meant to absorb.
    """
    if len(failed) == 0 or len(poses) == 0:
        return np.zeros(len(poses), dtype=bool)
    d = np.linalg.norm(poses[:, None, :3, 3] - failed[None, :, :3, 3], axis=-1)
    Ra = np.broadcast_to(poses[:, None, :3, :3], (len(poses), len(failed), 3, 3))
    Rb = np.broadcast_to(failed[None, :, :3, :3], Ra.shape)
    rot = grasp_rotation_error(Ra, Rb)
    return np.any((d < distance) & (rot < angle), axis=1)


def select_grasp(poses: np.ndarray, widths: np.ndarray, confidences: np.ndarray, errors: np.ndarray,
                 points: np.ndarray, ik: IK, cfg: SelectorConfig, execution: ExecutionConfig,
                 failed: np.ndarray | None = None, view: DepthView | None = None) -> Selection:
    """Pick the best feasible candidate among world-frame ``poses`` given observed world ``points``,
    skipping candidates near the ``failed`` (K, 4, 4) world grasps of earlier attempts; ``view`` (the
    depth image the points came from) enables the occlusion check."""
    scores = score_candidates(confidences, errors, cfg)
    sel = Selection(index=None, scores=scores)
    order = np.argsort(-scores, kind="stable")[: cfg.max_candidates]
    back = execution.pregrasp_distance
    ready_closing = ik.tcp_pose(READY_Q)[:3, 2]
    palm_samples = np.concatenate([_box_samples(_swept(b, back)) for b in (GRIPPER.palm_box(), GRIPPER.wrist_box())])
    repeat = near_failed(poses, np.zeros((0, 4, 4)) if failed is None else failed, cfg.retry_distance,
                         np.deg2rad(cfg.retry_angle_deg))
    for k in order:
        if repeat[k]:
            sel.rejected["repeat"] += 1
            continue
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
        if view is not None and np.any(view.hidden(palm_samples @ pose[:3, :3].T + pose[:3, 3], cfg.shadow_margin)):
            sel.rejected["occluded"] += 1
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
