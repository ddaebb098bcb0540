"""Grasp selection: rank candidates by score, then keep the first that passes the gripper prior.

Score: ``s = c − λ·RE`` (``confidence_minus_error``, the default) or the paper's printed ``s = c + RE``
(``paper_literal``); a missing reprojection error (NaN) counts as 0. Then, in this order, each rejection
counted:

1. ``width``: 0 < w ≤ the gripper's maximum opening;
2. ``collision``: the gripper's boxes (fingers at the candidate's width, palm, wrist; palm and wrist grown by
   ``palm_margin``), swept from the pre-grasp back-off to the grasp, contain fewer than ``collision_points``
   observed points and stay ``table_clearance`` above the table top;
3. ``occluded``: the palm and wrist, swept the same way, stay out of space the camera cannot see: a
   sample point of them lying more than ``shadow_margin`` behind the observed surface at its pixel
   (hidden behind an object) may be inside an unseen part of that object. Only the palm and wrist are
   checked: the fingers reach past the target into its own shadow by design, the palm stays above or
   behind it. Needs the depth image (``DepthView``); skipped without one;
4. ``enclosure``: the closing region between the fingers holds at least ``enclosed_points`` observed points,
   and they reach at least ``min_bite`` up from the fingertips along the approach (the fingers take a real
   bite of the object, not its top millimetres: a bowl's rim pinched 3 mm deep or a sphere held above its
   equator slips on the lift), unless the table stops the fingertips first (a flat object is as deep as it is);
5. ``ik``: IK reaches the pre-grasp and then the grasp within joint limits.

Before these, ``workspace``: a candidate whose grasp origin is not in the workspace over the table
(``ARM_WORKSPACE``: ``|x|, |y| ≤ sim.robot.WORKSPACE_HALF``, ``−2 cm ≤ z ≤ WORKSPACE_TOP``; in GIGA's protocols
``GIGA_WORKSPACE``, their 30 cm cube, to which they crop every detector's input) is not a grasp of anything the task is
about, whatever it encloses: the parked arm, its base and the place bin are in the image from some viewpoints,
and a grasp on them is executed after the arm has left (every real system bounds its workspace the same way).
Then ``repeat``: a candidate within ``retry_distance`` and ``retry_angle_deg`` (either symmetric form) of a
grasp that already failed in this trial (``failed``: world poses, both as executed and as the
candidate that was chosen, ``Selection.tried``) is skipped: a deterministic detector would otherwise retry
the same failing grasp until the consecutive failure limit ends the scene. (The executed pose alone is not
enough: the search below may have moved it by more than ``retry_distance`` from the candidate.)

Checks 2-4 are tried at the candidate's pose and, if it fails one, at poses shifted in its own frame along the
approach (±``approach_search``) and the closing axis (±``closing_search``) in steps of ``search_step``, nearest
shift first: a detector whose pose is right but whose distance to the camera is a centimetre or two off (a
scale error) still yields the grasp it meant. The shifted pose is the one executed. The enclosure check's
bite keeps the search honest: a grasp pulled back to clear the palm, or pushed just far enough to touch a
rim, passes only if its fingers still reach ``min_bite`` down the object.

Levelling (``level_deg`` > 0): before everything else, candidates approaching within
``level_deg`` of straight down are turned about their own y axis until their closing axis is horizontal
(``level_poses``).

Centring (``centre_range`` > 0, needs the depth image): the pose that passed is moved along its closing axis z
by ``dz = (z_min + z_max) / 2``, clipped to ±``centre_range``, where [z_min, z_max] is the extent along z of the
observed points in the closing region at the full jaw opening; it is kept if it passes the checks again. Only
when the closing axis is within ``CENTRE_VIEW_DEG`` of perpendicular to the camera ray through the grasp
origin: then both ends of the object along z face the camera, and the seen extent is the object's. (A closing
axis along the ray sees only the near face, whose extent says nothing about the far one.) And only when the
finger that the shift moves towards the object lands in space the camera saw free (``centring_blind``): a
seen extent that is one wall of a wide object (a lying tube whose far side the camera cannot see) would
otherwise put that finger onto the unseen part. That finger is checked only when the seen extent is under
``CENTRE_MIN_SPAN`` of the candidate's width: beside an object seen whole it stands in the object's own
shadow by design, like the fingers of every grasp.

Raw mode (``selector.mode = "raw"``, ``config.RAW_SELECTOR``): no levelling, pose search, centring, bite,
palm margin or occlusion check; the candidate that passes width, collision, enclosure and IK is executed at
the pose the detector predicted (in the symmetric form the arm reaches), with the executor's own
``grasp_depth`` push along the approach that every grasp of every mode gets (part of how the harness closes
a gripper, not a correction of the pose: the labels are made for it, ``shapes.household``). What the
assisted mode adds to that is what the selector repairs, not what the detector did.

The observed points come from the depth image (world frame), never from the simulator. Poses are world
frame ``T_world_grasp``. Each candidate is tried in both of its 180°-symmetric forms (the one closer to the
arm's ready wrist first). The executed grasp is pushed ``grasp_depth`` further along its approach when the
fingertips have room above the table.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kgn_bench import giga
from kgn_bench.config import ExecutionConfig, SelectorConfig
from kgn_bench.grasp import flip_180, grasp_rotation_error
from kgn_bench.gripper import GRIPPER, GripperBox, GripperGeometry, box_corners
from kgn_bench.sim.control import IK
from kgn_bench.sim.robot import READY_Q, WORKSPACE_HALF

__all__ = ["ARM_WORKSPACE", "CENTRE_MIN_SPAN", "CENTRE_VIEW_DEG", "GIGA_WORKSPACE", "REJECTIONS", "WORKSPACE_TOP",
           "DepthView", "GraspSelector",
           "Selection", "centre_offset", "centring_blind", "closing_z", "level_poses", "near_failed",
           "score_candidates", "search_offsets", "select_grasp", "valid_candidates"]

REJECTIONS = ("workspace", "repeat", "width", "collision", "occluded", "enclosure", "ik")
WORKSPACE_TOP = 0.4
"""Highest grasp origin (m above the table top) the selector accepts."""
ARM_WORKSPACE = (np.array([-WORKSPACE_HALF, -WORKSPACE_HALF, -0.02]), np.array([WORKSPACE_HALF, WORKSPACE_HALF,
                                                                             WORKSPACE_TOP]))
"""The box (world, m: lowest and highest corner) a grasp origin must lie in: the arm's workspace over the table."""
GIGA_WORKSPACE = (giga.WORKSPACE_ORIGIN, giga.WORKSPACE_ORIGIN + giga.WORKSPACE_SIZE)
"""GIGA's workspace cube (``kgn_bench.giga``): in GIGA's protocols every detector sees only what lies in it."""
CENTRE_VIEW_DEG = 45.0
"""Centring applies when the closing axis is at most this far from perpendicular to the camera ray."""

CENTRE_MIN_SPAN = 0.5
"""A seen extent along the closing axis under this fraction of the candidate's width may be part of the object
only (one wall of a lying tube): the centring then needs the finger it moves to land in seen space."""


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
    ``candidate`` is the chosen candidate's world pose as ranked (after levelling, before any shift).
    """

    index: int | None
    scores: np.ndarray
    rejected: dict[str, int] = field(default_factory=lambda: dict.fromkeys(REJECTIONS, 0))
    grasp: np.ndarray | None = None
    candidate: np.ndarray | None = None
    pregrasp: np.ndarray | None = None
    width: float = 0.0
    q_pregrasp: np.ndarray | None = None
    q_grasp: np.ndarray | None = None

    @property
    def tried(self) -> np.ndarray:
        """(K, 4, 4) the world poses a failure of this selection should rule out next time: the executed
        grasp and the candidate it came from (empty when nothing was selected)."""
        if self.grasp is None or self.candidate is None:
            return np.zeros((0, 4, 4))
        return np.stack([self.grasp, self.candidate])

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


def _grown(box: GripperBox, margin: float) -> GripperBox:
    """``box`` grown by ``margin`` (m) on every side."""
    return GripperBox(box.name, box.centre, box.half + margin)


def _union_bounds(boxes: list[GripperBox]) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper corners (3,) of the axis-aligned box holding all ``boxes`` (one frame)."""
    return (np.min([b.centre - b.half for b in boxes], axis=0), np.max([b.centre + b.half for b in boxes], axis=0))


def _inside(points_g: np.ndarray, box: GripperBox, shifts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grasp-frame points relative to each shift, ``(K, M, 3)``, and whether each lies inside ``box`` moved by
    that shift, ``(K, M)``; only the M points inside for some shift are kept."""
    lo, hi = box.centre - box.half + shifts.min(axis=0), box.centre + box.half + shifts.max(axis=0)
    points_g = points_g[np.all((points_g > lo) & (points_g < hi), axis=1)]  # inside for some shift
    rel = points_g[None] - shifts[:, None]
    return rel, np.all(np.abs(rel - box.centre) < box.half, axis=2)


def _count_inside(points_g: np.ndarray, box: GripperBox, shifts: np.ndarray) -> np.ndarray:
    """(K,) how many grasp-frame points lie inside ``box`` moved by each grasp-frame shift (K, 3)."""
    return np.count_nonzero(_inside(points_g, box, shifts)[1], axis=1)


def _enclosure(points_g: np.ndarray, region: GripperBox, shifts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For ``region`` (the closing region, fingertips at x = 0) moved by each grasp-frame shift (K, 3): how many
    grasp-frame points lie inside (K,), and the bite (K,), m: how far the deepest of them lies behind the
    fingertips along the approach, ``max(s_x − p_x)`` (0 when none)."""
    rel, inside = _inside(points_g, region, shifts)
    return np.count_nonzero(inside, axis=1), np.where(inside, -rel[..., 0], 0.0).max(axis=1, initial=0.0)


_AT_TABLE = 0.002
"""Fingertips this close (m) above ``table_clearance`` count as stopped by the table (the bite check is waived)."""


def _lowest_z(boxes: list[GripperBox], pose: np.ndarray) -> float:
    """World z of the lowest corner of ``boxes`` placed at ``pose``."""
    return float(min(box_corners(b, pose[None])[0, :, 2].min() for b in boxes))


def _grasp_depths(pose: np.ndarray, shifts: np.ndarray, width: float, depth: float, clearance: float,
                  g: GripperGeometry = GRIPPER) -> np.ndarray:
    """(K,) how far (≤ ``depth``) each shifted grasp (``pose`` moved by grasp-frame ``shifts`` (K, 3)) can
    move along its approach with the fingers' lowest corner ``clearance`` above the table top (z = 0)."""
    az = pose[2, 0]
    if az >= -1e-6 or depth == 0.0:
        return np.full(len(shifts), depth)
    fingers = [g.finger_box(s, width) for s in (1, -1)]
    low = _lowest_z(fingers, pose) + shifts @ pose[2, :3]
    return np.clip((low - clearance) / -az, 0.0, depth)


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


_CHECKS = (None, "collision", "occluded", "enclosure")


def _failures(pose: np.ndarray, shifts: np.ndarray, width: float, local: np.ndarray, boxes: list[GripperBox],
              palm_samples: np.ndarray, view: DepthView | None, cfg: SelectorConfig,
              g: GripperGeometry = GRIPPER) -> np.ndarray:
    """For ``pose`` moved by each grasp-frame shift (K, 3): the first gripper-prior check it fails, as an
    index into ``_CHECKS`` (0 = passes all). ``local``: observed points in the grasp frame of ``pose``;
    ``boxes``: the swept gripper boxes; ``width``: the candidate's (closing region) width."""
    R, t = pose[:3, :3], pose[:3, 3]
    low = _lowest_z(boxes, pose) + shifts @ R[2] < cfg.table_clearance - 1e-6
    hits = sum(_count_inside(local, b, shifts) for b in boxes)
    code = np.where(low | (hits >= cfg.collision_points), 1, 0)
    todo = np.flatnonzero(code == 0)
    if view is not None and len(todo):
        world = (palm_samples[None] + shifts[todo, None]) @ R.T + t
        hidden = view.hidden(world.reshape(-1, 3), cfg.shadow_margin).reshape(len(todo), -1).any(axis=1)
        code[todo[hidden]] = 2
    enclosed, bite = _enclosure(local, g.closing_region(width), shifts)
    if cfg.min_bite > 0:
        tips = _lowest_z([b for b in boxes if b.name.endswith("finger")], pose) + shifts @ R[2]
        shallow = (bite < cfg.min_bite) & (tips > cfg.table_clearance + _AT_TABLE)
    else:
        shallow = np.zeros(len(shifts), dtype=bool)
    code[(code == 0) & ((enclosed < cfg.enclosed_points) | shallow)] = 3
    return code


def centre_offset(local: np.ndarray, open_w: float, closing_world: np.ndarray, ray_world: np.ndarray,
                  limit: float, min_points: int, g: GripperGeometry = GRIPPER) -> float:
    """The shift (m) along the closing axis that centres the observed points between the open jaws.

    ``local``: observed points in the grasp frame; the ones inside ``g.closing_region(open_w)`` span
    [z_min, z_max]; the shift is ``(z_min + z_max) / 2`` clipped to ±``limit``. Zero when fewer than
    ``min_points`` points are there, or when the closing axis (world, unit) is more than ``CENTRE_VIEW_DEG``
    from perpendicular to ``ray_world`` (camera → grasp origin, unit).
    """
    if abs(float(closing_world @ ray_world)) > np.sin(np.deg2rad(CENTRE_VIEW_DEG)):
        return 0.0
    z = closing_z(local, open_w, g)
    if len(z) < min_points:
        return 0.0
    return float(np.clip((z.min() + z.max()) / 2.0, -limit, limit))


def closing_z(local: np.ndarray, open_w: float, g: GripperGeometry = GRIPPER) -> np.ndarray:
    """The z (closing axis) coordinates of the grasp-frame points ``local`` inside the closing region of
    gripper ``g`` at opening ``open_w``."""
    region = g.closing_region(open_w)
    return local[np.all(np.abs(local - region.centre) < region.half, axis=1), 2]


def centring_blind(pose: np.ndarray, shift: np.ndarray, open_w: float, view: DepthView, margin: float,
                   g: GripperGeometry = GRIPPER) -> bool:
    """Whether the finger that a centring ``shift`` (grasp frame of the world ``pose``, its z the centring
    step) moves towards the observed points would stand in space the camera cannot see: any of its box's
    sample points lies more than ``margin`` behind the observed surface (``DepthView.hidden``). A shift by
    dz > 0 moves the −z (right) finger inwards, dz < 0 the +z (left) one. The centring trusts the seen extent
    to be the object's; where that finger goes blind, the object may go on unseen."""
    side = -1 if shift[2] > 0 else 1
    samples = _box_samples(g.finger_box(side, open_w)) + shift
    world = samples @ pose[:3, :3].T + pose[:3, 3]
    return bool(view.hidden(world, margin).any())


def level_poses(poses: np.ndarray, max_tilt_deg: float) -> np.ndarray:
    """World grasps (N, 4, 4) whose approach x points within ``max_tilt_deg`` of straight down, turned about
    their own y axis (through the grasp origin) until the closing axis z is horizontal; the others as they are.

    With x' = cos β·x − sin β·z and z' = sin β·x + cos β·z (a rotation about y, which stays), z'_z = 0 gives
    tan β = −z_z / x_z. Objects rest on a horizontal table: a closing axis tilted by a few degrees only lowers
    one finger's outer corner towards the table, which then stops the grasp short of the depth it meant.
    """
    out = np.array(poses, dtype=float, copy=True)
    x, z = out[:, :3, 0].copy(), out[:, :3, 2].copy()
    down = x[:, 2] < -np.cos(np.deg2rad(max_tilt_deg))
    beta = np.arctan(-z[:, 2] / np.where(down, x[:, 2], -1.0))
    c, s = np.cos(beta)[:, None], np.sin(beta)[:, None]
    out[down, :3, 0] = (c * x - s * z)[down]
    out[down, :3, 2] = (s * x + c * z)[down]
    return out


RIGID_TOLERANCE = 1e-4
"""How far ``RᵀR`` may be from the identity (max abs entry) and ``det R`` from 1 for a rigid pose."""


def valid_candidates(poses: np.ndarray, widths: np.ndarray, confidences: np.ndarray) -> np.ndarray:
    """(N,) bool: the pose is a finite rigid transform (``RᵀR = I`` and ``det R = 1`` within
    ``RIGID_TOLERANCE``, last row ``[0, 0, 0, 1]``) and the width and confidence are finite."""
    n = len(poses)
    if n == 0:
        return np.zeros(0, dtype=bool)
    finite = np.all(np.isfinite(poses.reshape(n, -1)), axis=1) & np.isfinite(widths) & np.isfinite(confidences)
    safe = np.where(finite[:, None, None], poses, np.eye(4))
    R = safe[:, :3, :3]
    orthonormal = np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max(axis=(1, 2)) < RIGID_TOLERANCE
    proper = np.abs(np.linalg.det(R) - 1.0) < RIGID_TOLERANCE
    bottom = np.all(np.abs(safe[:, 3] - np.array([0.0, 0.0, 0.0, 1.0])) < RIGID_TOLERANCE, axis=1)
    return finite & orthonormal & proper & bottom


class GraspSelector:
    """The selector of one task: built from its ``SelectorConfig`` and ``ExecutionConfig`` and the arm's
    ``IK``; ``select`` picks the best feasible candidate of one capture.

    For each candidate, best score first: the retry memory (``repeat``), the width, then the gripper prior on
    the observed cloud (collision, occlusion, enclosure; ``_prior``, with the pose search and the centring),
    then the reach (IK of the pre-grasp and the grasp, for both symmetric forms; ``_reach``). All poses are
    world-frame ``T_world_grasp``.
    """

    def __init__(self, cfg: SelectorConfig, execution: ExecutionConfig, ik: IK | None,
                 workspace: tuple[np.ndarray, np.ndarray] = ARM_WORKSPACE) -> None:
        self.mode = cfg.mode
        cfg = cfg.effective()
        self.cfg, self.execution, self.ik = cfg, execution, ik
        self.workspace = workspace
        self.g = g = execution.geometry
        floating = execution.hand == "floating"
        if (ik is None) != floating:
            raise ValueError("the selector needs the arm's IK exactly when the task's hand is the arm")
        self.grasp_depth = 0.0 if floating else execution.grasp_depth
        self.back = giga.PREGRASP_DISTANCE if floating else execution.pregrasp_distance
        self.ready_closing = None if ik is None else ik.tcp_pose(READY_Q)[:3, 2]
        self.palm_samples = np.concatenate([_box_samples(b.swept(self.back)) for b in (g.palm_box(), g.wrist_box())])
        self.offsets = search_offsets(cfg)
        # every grasp-frame point a check can look at lies in the boxes' union, moved by the largest shifts
        self.margin = np.array([float(np.abs(self.offsets[:, 0]).max(initial=0.0)) + self.grasp_depth, 0.0,
                                float(np.abs(self.offsets[:, 1]).max(initial=0.0)) + cfg.centre_range]) + 1e-6

    def select(self, poses: np.ndarray, widths: np.ndarray, confidences: np.ndarray, errors: np.ndarray,
               points: np.ndarray, failed: np.ndarray | None = None, view: DepthView | None = None) -> Selection:
        """Pick the best feasible candidate among world-frame ``poses`` given observed world ``points``,
        skipping candidates near the ``failed`` (K, 4, 4) world grasps of earlier attempts; ``view`` (the
        depth image the points came from) enables the occlusion check and the centring. A candidate that
        fails the gripper prior where it is is tried shifted by ``search_offsets`` (the first shift that passes
        is kept); its rejection is counted under the check its unshifted pose failed. Candidates whose pose is
        not a finite rigid transform, or whose width or confidence is not finite, are never executed: they are
        counted as ``invalid_pose``."""
        cfg = self.cfg
        valid = valid_candidates(poses, widths, confidences)
        poses = np.where(valid[:, None, None], poses, np.eye(4))
        if cfg.level_deg > 0:
            poses = level_poses(poses, cfg.level_deg)
        scores = np.where(valid, score_candidates(np.where(valid, confidences, 0.0), errors, cfg), -np.inf)
        sel = Selection(index=None, scores=scores)
        if not valid.all():
            sel.rejected["invalid_pose"] = int((~valid).sum())  # only when it happens: records stay as they were
        order = np.argsort(-scores, kind="stable")
        order = order[valid[order]][: cfg.max_candidates]
        repeat = near_failed(poses, np.zeros((0, 4, 4)) if failed is None else failed, cfg.retry_distance,
                             np.deg2rad(cfg.retry_angle_deg))
        t = poses[:, :3, 3]
        lo, hi = self.workspace
        over_table = np.all((t >= lo) & (t <= hi), axis=1)
        for k in order:
            if not over_table[k]:
                sel.rejected["workspace"] += 1
                continue
            if repeat[k] and self.mode != "top":
                sel.rejected["repeat"] += 1
                continue
            w = float(widths[k])
            if not (0.0 < w <= self.g.max_width or (self.mode == "top" and w > 0.0)):
                sel.rejected["width"] += 1
                continue
            open_w = float(self.g.opening(w))
            if self.mode == "top":
                shifted, code = poses[k], 0
            else:
                shifted, code = self._prior(poses[k], w, open_w, points, view)
            if shifted is None:
                sel.rejected[_CHECKS[code]] += 1
                continue
            reached = self._reach(shifted)
            if reached is None:
                sel.rejected["ik"] += 1
                continue
            sel.index = int(k)
            sel.grasp, sel.pregrasp, sel.q_pregrasp, sel.q_grasp = reached
            sel.width = open_w
            sel.candidate = poses[k].copy()
            return sel
        return sel

    def _prior(self, pose: np.ndarray, w: float, open_w: float, points: np.ndarray, view: DepthView | None
               ) -> tuple[np.ndarray | None, int]:
        """The candidate moved by the first search shift that passes the gripper prior, then centred on the
        observed points between the jaws; ``(None, code)`` with the failed check of the unshifted pose."""
        cfg = self.cfg
        g = self.g
        boxes = [(_grown(b, cfg.palm_margin) if b.name in ("palm", "wrist") else b).swept(self.back)
                 for b in g.boxes(open_w)]
        R = pose[:3, :3]
        local0 = (points - pose[:3, 3]) @ R  # observed points in the candidate's grasp frame
        lo, hi = _union_bounds([*boxes, g.closing_region(open_w)])
        local0 = local0[np.all((local0 > lo - self.margin) & (local0 < hi + self.margin), axis=1)]
        shifts = np.c_[self.offsets[:, 0], np.zeros(len(self.offsets)), self.offsets[:, 1]]
        shifts[:, 0] += _grasp_depths(pose, shifts, open_w, self.grasp_depth, cfg.table_clearance, g)
        args = (w, local0, boxes, self.palm_samples, view if cfg.occlusion else None, cfg, g)
        codes = _failures(pose, shifts[:1], *args)  # most candidates pass or fail where they are
        if codes[0] != 0 and len(shifts) > 1:
            codes = np.concatenate([codes, _failures(pose, shifts[1:], *args)])
        passing = np.flatnonzero(codes == 0)
        if len(passing) == 0:
            return None, int(codes[0])
        shift = shifts[passing[0]]
        if cfg.centre_range > 0 and view is not None:
            ray = pose[:3, 3] + R @ shift - view.camera_pose[:3, 3]
            dz = centre_offset(local0 - shift, open_w, R[:, 2], ray / np.linalg.norm(ray), cfg.centre_range,
                               cfg.enclosed_points, g)
            centred = shift + np.array([0.0, 0.0, dz])
            if dz != 0.0 and _failures(pose, centred[None], *args)[0] == 0:
                z = closing_z(local0 - shift, open_w, g)
                partial = z.max() - z.min() < CENTRE_MIN_SPAN * w  # perhaps one wall of the object
                if not (partial and centring_blind(pose, centred, open_w, view, cfg.shadow_margin, g)):
                    shift = centred
        moved = pose.copy()
        moved[:3, 3] += R @ shift
        return moved, 0

    def _reach(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """``(grasp, pregrasp, q_pregrasp, q_grasp)`` for the first of the two symmetric forms of ``pose``
        (the one whose closing axis is nearer the ready wrist's first) that the arm reaches, else None. A
        floating hand (no IK) reaches every pose, as predicted, with no joint solutions."""
        if self.ik is None:
            pre = pose.copy()
            pre[:3, 3] -= self.back * pose[:3, 0]
            return pose, pre, None, None
        flipped = flip_180(pose[None])[0]
        forms = (pose, flipped) if pose[:3, 2] @ self.ready_closing >= 0 else (flipped, pose)
        for form in forms:
            pre = form.copy()
            pre[:3, 3] -= self.back * form[:3, 0]
            r_pre = self.ik.solve(pre)
            if not r_pre.ok:
                continue
            r_grasp = self.ik.solve(form, r_pre.q)
            if r_grasp.ok:
                return form, pre, r_pre.q, r_grasp.q
        return None


def select_grasp(poses: np.ndarray, widths: np.ndarray, confidences: np.ndarray, errors: np.ndarray,
                 points: np.ndarray, ik: IK | None, cfg: SelectorConfig, execution: ExecutionConfig,
                 failed: np.ndarray | None = None, view: DepthView | None = None) -> Selection:
    """``GraspSelector(cfg, execution, ik).select(...)`` in one call."""
    return GraspSelector(cfg, execution, ik).select(poses, widths, confidences, errors, points, failed, view)
