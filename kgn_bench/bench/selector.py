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

Checks 2-4 are tried at the candidate's pose and, if it fails one, at poses shifted in its own frame along the
approach (±``approach_search``) and the closing axis (±``closing_search``) in steps of ``search_step``, nearest
shift first: a detector whose pose is right but whose distance to the camera is a centimetre or two off (a
scale error) still yields the grasp it meant. The shifted pose is the one executed.

Centring (``centre_range`` > 0, needs the depth image): the pose that passed is moved along its closing axis z
by ``dz = (z_min + z_max) / 2``, clipped to ±``centre_range``, where [z_min, z_max] is the extent along z of the
observed points in the closing region at the full jaw opening; it is kept if it passes the checks again. Only
when the closing axis is within ``CENTRE_VIEW_DEG`` of perpendicular to the camera ray through the grasp
origin: then both ends of the object along z face the camera, and the seen extent is the object's. (A closing
axis along the ray sees only the near face, whose extent says nothing about the far one.)

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

__all__ = ["CENTRE_VIEW_DEG", "REJECTIONS", "DepthView", "Selection", "centre_offset", "near_failed",
           "score_candidates", "search_offsets", "select_grasp"]

REJECTIONS = ("repeat", "width", "collision", "occluded", "enclosure", "ik")
CENTRE_VIEW_DEG = 45.0
"""Centring applies when the closing axis is at most this far from perpendicular to the camera ray."""


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


def _union_bounds(boxes: list[GripperBox]) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper corners (3,) of the axis-aligned box holding all ``boxes`` (one frame)."""
    return (np.min([b.centre - b.half for b in boxes], axis=0), np.max([b.centre + b.half for b in boxes], axis=0))


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


def search_offsets(cfg: SelectorConfig) -> np.ndarray:
    """Grasp-frame shifts (dx along the approach, dz along the closing axis), metres, (K, 2): every multiple of
    ``search_step`` with |dx| ≤ ``approach_search`` and |dz| ≤ ``closing_search``, nearest first ((0, 0) first)."""
    step = cfg.search_step
    nx = int(np.floor(cfg.approach_search / step + 1e-9)) if step > 0 else 0
    nz = int(np.floor(cfg.closing_search / step + 1e-9)) if step > 0 else 0
    grid = np.array([(i * step, j * step) for i in range(-nx, nx + 1) for j in range(-nz, nz + 1)])
    return grid[np.lexsort((grid[:, 1], grid[:, 0], np.hypot(grid[:, 0], grid[:, 1])))]


def _check(pose: np.ndarray, open_w: float, width: float, local: np.ndarray, boxes: list[GripperBox],
           palm_samples: np.ndarray, view: DepthView | None, cfg: SelectorConfig) -> str | None:
    """The first gripper-prior check (collision, occluded, enclosure) that ``pose`` fails, None if it passes.
    ``local``: observed points in the grasp frame of ``pose``."""
    corners = np.concatenate([box_corners(b, pose[None])[0] for b in boxes])
    hits = sum(_count_inside(local, b) for b in boxes)
    if corners[:, 2].min() < cfg.table_clearance - 1e-6 or hits >= cfg.collision_points:
        return "collision"
    if view is not None and np.any(view.hidden(palm_samples @ pose[:3, :3].T + pose[:3, 3], cfg.shadow_margin)):
        return "occluded"
    if _count_inside(local, GRIPPER.closing_region(width)) < cfg.enclosed_points:
        return "enclosure"
    return None


def centre_offset(local: np.ndarray, open_w: float, closing_world: np.ndarray, ray_world: np.ndarray,
                  limit: float, min_points: int) -> float:
    """The shift (m) along the closing axis that centres the observed points between the open jaws.

    ``local``: observed points in the grasp frame; the ones inside ``GRIPPER.closing_region(open_w)`` span
    [z_min, z_max]; the shift is ``(z_min + z_max) / 2`` clipped to ±``limit``. Zero when fewer than
    ``min_points`` points are there, or when the closing axis (world, unit) is more than ``CENTRE_VIEW_DEG``
    from perpendicular to ``ray_world`` (camera → grasp origin, unit).
    """
    if abs(float(closing_world @ ray_world)) > np.sin(np.deg2rad(CENTRE_VIEW_DEG)):
        return 0.0
    region = GRIPPER.closing_region(open_w)
    z = local[np.all(np.abs(local - region.centre) < region.half, axis=1), 2]
    if len(z) < min_points:
        return 0.0
    return float(np.clip((z.min() + z.max()) / 2.0, -limit, limit))


def select_grasp(poses: np.ndarray, widths: np.ndarray, confidences: np.ndarray, errors: np.ndarray,
                 points: np.ndarray, ik: IK, cfg: SelectorConfig, execution: ExecutionConfig,
                 failed: np.ndarray | None = None, view: DepthView | None = None) -> Selection:
    """Pick the best feasible candidate among world-frame ``poses`` given observed world ``points``,
    skipping candidates near the ``failed`` (K, 4, 4) world grasps of earlier attempts; ``view`` (the
    depth image the points came from) enables the occlusion check. A candidate that fails the gripper prior
    where it is is tried shifted by ``search_offsets`` (the first shift that passes is kept); its rejection is
    counted under the check its unshifted pose failed."""
    scores = score_candidates(confidences, errors, cfg)
    sel = Selection(index=None, scores=scores)
    order = np.argsort(-scores, kind="stable")[: cfg.max_candidates]
    back = execution.pregrasp_distance
    ready_closing = ik.tcp_pose(READY_Q)[:3, 2]
    palm_samples = np.concatenate([_box_samples(_swept(b, back)) for b in (GRIPPER.palm_box(), GRIPPER.wrist_box())])
    repeat = near_failed(poses, np.zeros((0, 4, 4)) if failed is None else failed, cfg.retry_distance,
                         np.deg2rad(cfg.retry_angle_deg))
    offsets = search_offsets(cfg)
    # every grasp-frame point a check can look at lies in the boxes' union, moved by the largest shifts
    margin = np.array([float(np.abs(offsets[:, 0]).max(initial=0.0)) + execution.grasp_depth, 0.0,
                       float(np.abs(offsets[:, 1]).max(initial=0.0)) + cfg.centre_range]) + 1e-6
    for k in order:
        if repeat[k]:
            sel.rejected["repeat"] += 1
            continue
        w = float(widths[k])
        if not (0.0 < w <= GRIPPER.max_width):
            sel.rejected["width"] += 1
            continue
        open_w = float(GRIPPER.opening(w))
        boxes = [_swept(b, back) for b in GRIPPER.boxes(open_w)]
        R = poses[k][:3, :3]
        local0 = (points - poses[k][:3, 3]) @ R  # observed points in the candidate's grasp frame
        lo, hi = _union_bounds([*boxes, GRIPPER.closing_region(open_w)])
        local0 = local0[np.all((local0 > lo - margin) & (local0 < hi + margin), axis=1)]
        first_failure, pose = None, None
        for dx, dz in offsets:
            shifted = poses[k].copy()
            shifted[:3, 3] += dx * R[:, 0] + dz * R[:, 2]
            depth = _grasp_depth(shifted, open_w, execution.grasp_depth, cfg.table_clearance)
            shifted[:3, 3] += depth * R[:, 0]
            local = local0 - np.array([dx + depth, 0.0, dz])
            failure = _check(shifted, open_w, w, local, boxes, palm_samples, view, cfg)
            first_failure = first_failure or failure
            if failure is None:
                pose = shifted
                break
        if pose is None:
            sel.rejected[first_failure] += 1
            continue
        if cfg.centre_range > 0 and view is not None:
            local = local0 - (pose[:3, 3] - poses[k][:3, 3]) @ R
            ray = pose[:3, 3] - view.camera_pose[:3, 3]
            dz = centre_offset(local, open_w, R[:, 2], ray / np.linalg.norm(ray), cfg.centre_range,
                               cfg.enclosed_points)
            if dz != 0.0:
                centred = pose.copy()
                centred[:3, 3] += dz * R[:, 2]
                if _check(centred, open_w, w, local - np.array([0.0, 0.0, dz]), boxes, palm_samples, view,
                          cfg) is None:
                    pose = centred
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
