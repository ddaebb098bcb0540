"""The antipodal detector: a geometric point-cloud baseline (GPD-style antipodal sampling), no learning.

It sees only the observation (depth, intrinsics, camera pose) and one fact every tabletop system knows: the
table top is the world plane z = 0. Steps, all vectorised:

1. back-project every ``stride``-th depth pixel; points more than ``min_height`` above the table are the
   object cloud, those above ``collision_height`` the obstacle cloud; 8-connected components of the object
   mask (OpenCV) stand in for objects;
2. normals at full resolution on the objects' bounding box, from one-sided image differences among object
   pixels (towards the neighbour with the smaller depth jump, so silhouettes keep their grazing normals
   and no normal mixes an object with the table), smoothed over 3×3 pixels, facing the camera; seeds only
   where the 3×3 normals agree (not on an edge);
3. ``seeds`` random object points; at each two families of gripper frames: closing axis along the normal
   (the seed is a finger contact, its partner lies along −normal) with ``approaches`` approach directions
   around it, tilted from the most downward one; and approach along −normal with ``closings`` closing axes
   around it;
4. per frame, in the seed's neighbourhood (≤ ``neighbours`` points within ``radius``): the seed's object
   points in the finger slab (|y| ≤ finger breadth/2) give the extent along the closing axis — the run of
   occupied 3 mm bins around the seed, split at gaps a finger fits into; its ends are the two contacts —
   the fingertips go ``depth`` past the first surface along the approach (less near the table), the extent
   is re-measured inside the closing region, and width = extent + 2·``margin``. The partner contact is not
   required to be seen: from one view the far side of a box or a lying stick never is, so a pair search
   on observed points alone finds nothing there; an unseen contact only scores lower (step 6);
5. rejected, stage by stage (later stages see fewer candidates): too wide for the gripper, too few points
   between the fingers, a box below the table, or any obstacle point inside the fingers, palm or wrist
   (``GRIPPER``'s boxes at the selector's opening, swept back the pre-grasp distance and ``push`` forward);
6. scored in [0, 1], a weighted sum: antipodality 0.3 (per contact, the best normal of the points at that
   end of the closing region against the closing axis: 1 parallel, 0 at twice the ``cone_deg`` friction
   cone; a contact the camera cannot see scores 0), approach from above 0.15, closeness to the object's
   centroid 0.15, closing across the object's footprint (its horizontal minor axis, weighted by how
   elongated the footprint is) 0.15, finger depth 0.1, coverage of the finger breadth 0.05, approach from
   the camera side (the palm stays in seen space) 0.1;
7. near-duplicates (≤ 1 cm, ≤ 15° in either 180° form) removed; the best ``top`` returned, camera frame,
   confidence = score, no reprojection error (NaN).

All randomness (seeds, neighbourhood subsampling) comes from ``reset(seed)``. The names in double backquotes
above are the fields of ``AntipodalConfig`` (``kgn_bench.detectors.antipodal_config``).
"""

from __future__ import annotations

import cv2
import numpy as np

from kgn_bench.config import ExecutionConfig
from kgn_bench.geometry import backproject, backproject_strided, frame_from_xz, invert_pose
from kgn_bench.gripper import GRIPPER

from .antipodal_config import AntipodalConfig
from .base import Candidates, Observation

__all__ = ["AntipodalConfig", "AntipodalDetector", "estimate_normals"]

_BIN = 0.003
"""Bin size along the closing axis when measuring an object part's extent (``_extent``)."""
_GAP = GRIPPER.finger_thickness + 0.005
"""A gap along the closing axis at least this wide ends an object part: a finger fits into it."""


def estimate_normals(points: np.ndarray, valid: np.ndarray, max_jump: float = 0.03) -> tuple[np.ndarray, np.ndarray]:
    """Normals of an organised camera-frame cloud ``points`` (h, w, 3) with ``valid`` (h, w) pixels.

    Tangents are one-sided differences towards the neighbour with the smaller depth jump (a silhouette
    pixel keeps the surface it lies on); a pixel whose best jump exceeds ``max_jump`` m has no normal.
    Returns unit normals (h, w, 3) facing the camera (n · p < 0) and the (h, w) mask of those defined.
    """

    def tangent(axis: int) -> tuple[np.ndarray, np.ndarray]:
        d = np.diff(points, axis=axis)
        ok = np.logical_and(np.take(valid, range(1, valid.shape[axis]), axis=axis),
                            np.take(valid, range(valid.shape[axis] - 1), axis=axis))
        jump = np.where(ok, np.abs(d[..., 2]), np.inf)
        pad_d = [(0, 0)] * 3
        pad_j = [(0, 0)] * 2
        pad_d[axis], pad_j[axis] = (0, 1), (0, 1)
        fwd, jf = np.pad(d, pad_d), np.pad(jump, pad_j, constant_values=np.inf)
        pad_d[axis], pad_j[axis] = (1, 0), (1, 0)
        bwd, jb = np.pad(d, pad_d), np.pad(jump, pad_j, constant_values=np.inf)
        use_f = jf <= jb
        return np.where(use_f[..., None], fwd, bwd), np.minimum(jf, jb) < max_jump

    du, ok_u = tangent(1)
    dv, ok_v = tangent(0)
    n = np.cross(du, dv)
    norm = np.linalg.norm(n, axis=-1)
    ok = valid & ok_u & ok_v & (norm > 1e-12)
    n = np.where(ok[..., None], n / np.maximum(norm, 1e-12)[..., None], 0.0)
    n = np.where((np.sum(n * points, axis=-1) > 0.0)[..., None], -n, n)
    return n, ok


def _smooth_normals(n: np.ndarray, mask: np.ndarray, min_coherence: float = 0.97
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Average unit normals over the 3×3 neighbourhood of pixels in ``mask``; renormalised. Also returns
    where they are defined and where they are coherent (the mean of the neighbourhood's unit normals has
    length ≥ ``min_coherence``: not on an edge or a crease)."""
    w = mask.astype(np.float64)
    acc = cv2.boxFilter(n * w[..., None], -1, (3, 3), normalize=False, borderType=cv2.BORDER_CONSTANT)
    count = cv2.boxFilter(w, -1, (3, 3), normalize=False, borderType=cv2.BORDER_CONSTANT)
    norm = np.linalg.norm(acc, axis=-1)
    ok = mask & (norm > 1e-6)
    coherent = ok & (norm >= min_coherence * np.maximum(count, 1.0)) & (count >= 4)
    return np.where(ok[..., None], acc / np.maximum(norm, 1e-12)[..., None], 0.0), ok, coherent


def _perp_basis(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For unit vectors v (N, 3): e1 ⟂ v, the most downward such direction (any where v is vertical), and
    e2 = v × e1."""
    down = np.array([0.0, 0.0, -1.0])
    e1 = down - (v @ down)[:, None] * v
    flat = np.linalg.norm(e1, axis=1) < 1e-3
    alt = np.array([1.0, 0.0, 0.0]) - v[:, :1] * v
    e1 = np.where(flat[:, None], alt, e1)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(v, e1)


class AntipodalDetector:
    """Antipodal grasp sampling on the observed point cloud (see the module docstring), with the settings of
    ``config`` (default ``AntipodalConfig()``)."""

    name = "antipodal"
    privileged = False

    def __init__(self, config: AntipodalConfig | None = None) -> None:
        self.config = AntipodalConfig() if config is None else config
        self.cone = np.deg2rad(self.config.cone_deg)
        self.pregrasp_distance = ExecutionConfig().pregrasp_distance
        self._rng = np.random.default_rng(0)

    def configure(self, execution: ExecutionConfig) -> None:
        """Take the task's execution settings: the clearance check sweeps the gripper back from the grasp by
        the pre-grasp distance the arm will really use."""
        self.pregrasp_distance = execution.pregrasp_distance

    def reset(self, seed: list[int]) -> None:
        self._rng = np.random.default_rng([*seed, 0xA9])

    # -- the cloud -------------------------------------------------------------------------------
    def _cloud(self, obs: Observation) -> dict[str, np.ndarray] | None:
        """Obstacle points (every ``stride``-th pixel above ``collision_height``) with, for the object
        points among them, world normals (estimated at full resolution) and component labels."""
        cfg, s = self.config, self.config.stride
        depth = obs.depth.astype(np.float64)
        K, T = obs.intrinsics.K, obs.camera_pose
        h, w = depth.shape
        ray_x = (np.arange(w) - K[0, 2]) / K[0, 0]
        ray_y = (np.arange(h) - K[1, 2]) / K[1, 1]
        height = depth * (T[2, 0] * ray_x[None] + T[2, 1] * ray_y[:, None] + T[2, 2]) + T[2, 3]
        valid = depth > 0
        obj = valid & (height > cfg.min_height)
        keep = valid[::s, ::s] & (height[::s, ::s] > cfg.collision_height)
        obj_s = obj[::s, ::s]
        if np.count_nonzero(obj_s) < cfg.min_enclosed:
            return None
        normals, has_normal, smooth = _strided_normals(depth, K, obj, s)
        _, labels = cv2.connectedComponents(obj_s.astype(np.uint8), connectivity=8)
        pc = backproject_strided(obs.depth, K, s)[keep]
        return {
            "points": pc @ T[:3, :3].T + T[:3, 3],
            "normals": normals[keep] @ T[:3, :3].T,
            "has_normal": has_normal[keep],
            "coherent": smooth[keep],
            "object": obj_s[keep],
            "label": labels[keep],
        }

    # -- candidates ------------------------------------------------------------------------------
    def detect(self, observation: Observation) -> Candidates:
        """Candidates in the camera frame (``Candidates``: grasp poses T_camera_grasp, widths, scores as
        confidences), best first; empty when the cloud holds no object or no coherent seed."""
        observation.validate()
        cloud = self._cloud(observation)
        if cloud is None:
            return Candidates.empty()
        pts, lab, is_obj = cloud["points"], cloud["label"], cloud["object"]
        seedable = np.flatnonzero(is_obj & cloud["coherent"])
        if len(seedable) == 0:
            return Candidates.empty()
        seeds = np.sort(self._rng.choice(seedable, size=min(self.config.seeds, len(seedable)), replace=False))
        p, n = pts[seeds], cloud["normals"][seeds]
        nb, nb_ok = self._neighbourhoods(pts, p)
        cen, major, aniso = _footprints(pts[is_obj], lab[is_obj], int(lab.max()) + 1)
        R, seed_of = _seed_frames(n, self.config.approaches, self.config.closings)
        local = {
            "rel": (pts[nb] - p[:, None]).astype(np.float32),
            "normals": cloud["normals"][nb].astype(np.float32),
            "ok": nb_ok,
            "same": nb_ok & is_obj[nb] & (lab[nb] == lab[seeds][:, None]),
        }
        obj_of = lab[seeds]
        cam_pos = observation.camera_pose[:3, 3]
        chunk = self.config.chunk
        with np.errstate(invalid="ignore"):
            out = [self._evaluate(R[i:i + chunk], seed_of[i:i + chunk], p, local, cen[obj_of], major[obj_of],
                                  aniso[obj_of], cam_pos)
                   for i in range(0, len(R), chunk)]
        return self._best(out, observation.camera_pose)

    def _neighbourhoods(self, pts: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per seed ``p`` (M, 3), the indices (M, k) of up to ``neighbours`` random points of ``pts`` (world)
        within ``radius`` (squared distances |q|² − 2 p·q + |p|² in float32), and which of them are (an index
        is a filler where fewer points are within reach)."""
        cfg = self.config
        q = pts.astype(np.float32)
        d2 = np.sum(q**2, axis=1)[None] - 2.0 * (p.astype(np.float32) @ q.T) + np.sum(p**2, axis=1)[:, None]
        key = np.where(d2 < cfg.radius**2, self._rng.random(d2.shape), np.inf)
        k = min(cfg.neighbours, pts.shape[0])
        nb = np.argpartition(key, k - 1, axis=1)[:, :k] if k < pts.shape[0] else np.tile(np.arange(k), (len(p), 1))
        return nb, np.isfinite(np.take_along_axis(key, nb, axis=1))

    def _best(self, out: list[tuple[np.ndarray, np.ndarray, np.ndarray]], camera_pose: np.ndarray) -> Candidates:
        """The evaluated chunks ``out`` (world poses, widths, scores) sorted by score, near-duplicates removed
        (≤ 1 cm, ≤ 15°), the best ``top`` as camera-frame candidates T_camera_grasp = T_world_camera⁻¹ ·
        T_world_grasp."""
        poses = np.concatenate([o[0] for o in out]) if out else np.zeros((0, 4, 4))
        widths = np.concatenate([o[1] for o in out]) if out else np.zeros(0)
        scores = np.concatenate([o[2] for o in out]) if out else np.zeros(0)
        if len(poses) == 0:
            return Candidates.empty()
        order = np.argsort(-scores, kind="stable")
        keep = _dedupe(poses[order], distance=0.01, angle=np.deg2rad(15.0))[: self.config.top]
        idx = order[keep]
        cam = invert_pose(camera_pose) @ poses[idx]
        return Candidates(cam, widths[idx], scores[idx], np.full(len(idx), np.nan))

    def _evaluate(self, R, seed_of, p, local, cen, major, aniso, cam_pos):
        """World poses, widths and scores of the feasible frames ``R`` (G, 3, 3) at seeds ``seed_of``, given
        each seed's neighbourhood ``local`` (positions relative to the seed, normals, valid and same-object
        masks, (M, K, ...)) and, per seed, its object's centroid, footprint axis and anisotropy. Candidates
        are dropped as soon as a stage rejects them, so later stages see fewer rows."""
        loc = local["rel"][seed_of] @ R.astype(np.float32)  # (G, K, 3): grasp-axis coordinates from the seed
        a, b, c = loc[..., 0], loc[..., 1], loc[..., 2]
        inside = local["same"][seed_of] & (np.abs(b) <= GRIPPER.finger_breadth / 2.0)  # same object, finger slab
        # 1. extent along the closing axis: the run of occupied bins around the seed, ended by finger-sized gaps
        keep, c_lo, c_hi, a_min, w1 = self._closing_extent(a, c, inside)
        R, seed_of, a, b, c, inside, c_lo, c_hi, a_min, w1 = _rows(
            keep, R, seed_of, a, b, c, inside, c_lo, c_hi, a_min, w1)
        # 2. fingertip depth: `depth` past the first surface, less where the fingers would reach the table
        pz = p[seed_of, 2]
        a_tip = self._fingertip_depth(R, pz, a_min, c_lo, c_hi, w1)
        # 3. re-measure inside the closing region
        keep, reg, c_lo, c_hi, c_mid, width, w_open = self._closing_region(R, pz, a, c, inside, a_tip, a_min,
                                                                           c_lo, c_hi)
        R, seed_of, a, b, c, reg, a_tip, a_min, c_lo, c_hi, c_mid, width, w_open = _rows(
            keep, R, seed_of, a, b, c, reg, a_tip, a_min, c_lo, c_hi, c_mid, width, w_open)
        # 4. clearance: no obstacle point in the fingers, palm or wrist, swept from the pre-grasp to the push
        keep = self._clear(a - a_tip[:, None], np.abs(b), np.abs(c - c_mid[:, None]), w_open, local["ok"][seed_of])
        R, seed_of, b, c, reg, a_tip, a_min, c_lo, c_hi, c_mid, width = _rows(
            keep, R, seed_of, b, c, reg, a_tip, a_min, c_lo, c_hi, c_mid, width)
        # 5. score, each term in [0, 1]
        origin = p[seed_of] + R[:, :, 0] * a_tip[:, None] + R[:, :, 2] * c_mid[:, None]
        nz = (local["normals"][seed_of] @ R[:, :, 2][:, :, None].astype(np.float32))[..., 0]
        score = self._score(R, origin, nz, reg, b, c, c_lo, c_hi, a_tip - a_min, cen[seed_of], major[seed_of],
                            aniso[seed_of], cam_pos)
        poses = np.zeros((len(R), 4, 4))
        poses[:, :3, :3] = R
        poses[:, :3, 3] = origin
        poses[:, 3, 3] = 1.0
        return poses, width, score

    def _closing_extent(self, a, c, inside):
        """Stage 1 per frame, from the grasp-axis coordinates ``a`` (approach) and ``c`` (closing) of the
        neighbourhood (G, K) and the mask ``inside`` of its same-object points in the finger slab: the extent
        [c_lo, c_hi] of the seed's part within a finger length of the seed along the approach (``_extent``),
        the first surface a_min along the approach in that extent, the width c_hi − c_lo + 2 · margin, and
        which frames are kept (a surface found, the width fits the gripper's opening)."""
        g = GRIPPER
        col = inside & (np.abs(a) <= g.finger_length)
        c_lo, c_hi = _extent(c, col, g.max_width)
        a_min = np.where(col & (c >= c_lo[:, None]) & (c <= c_hi[:, None]), a, np.inf).min(1)
        w1 = c_hi - c_lo + 2 * self.config.margin
        keep = np.isfinite(a_min) & (w1 <= g.max_width - g.open_margin)
        return keep, c_lo, c_hi, a_min, w1

    def _fingertip_depth(self, R, pz, a_min, c_lo, c_hi, w1):
        """Stage 2: the fingertips' coordinate a_tip along the approach, a_min + ``depth``, lowered where the
        lowest finger point (the fingers at the opening of width ``w1``, centred on the extent) would come
        closer than ``table_clearance`` to the table; ``pz`` is the seed's world height and R[:, 2] the world
        z row of the grasp rotations (only an approach going down, x_z < 0, can reach the table)."""
        g, cfg = GRIPPER, self.config
        xz, yz, zz = R[:, 2, 0], R[:, 2, 1], R[:, 2, 2]
        w_open1 = g.opening(w1)
        low_rel = (np.minimum(-g.finger_length * xz, 0.0) - np.abs(yz) * (g.finger_breadth / 2.0)
                   - np.abs(zz) * (w_open1 / 2 + g.finger_thickness))
        limit = (cfg.table_clearance - low_rel - pz - zz * 0.5 * (c_hi + c_lo)) / np.where(xz < -1e-6, xz, -1.0)
        return np.where(xz < -1e-6, np.minimum(a_min + cfg.depth, limit), a_min + cfg.depth)

    def _closing_region(self, R, pz, a, c, inside, a_tip, a_min, c_lo, c_hi):
        """Stage 3: the closing region (``inside`` points between a_tip − finger length and a_tip along the
        approach, within 1 mm of the extent), its extent [c_lo, c_hi] and middle c_mid re-measured there, the
        width max(c_hi − c_lo + 2 · margin, min_width) and its opening, and which frames are kept (fingertips
        at least ``min_depth`` past the surface, ``min_enclosed`` points between the fingers, no gripper box
        below ``table_clearance``, the box origins at world height pz + x_z · a_tip + z_z · c_mid)."""
        g, cfg = GRIPPER, self.config
        reg = inside & (a >= (a_tip - g.finger_length)[:, None]) & (a <= a_tip[:, None]) & \
            (c >= (c_lo - 1e-3)[:, None]) & (c <= (c_hi + 1e-3)[:, None])
        n_enc = reg.sum(1)
        c_hi = np.where(reg, c, -np.inf).max(1)
        c_lo = np.where(reg, c, np.inf).min(1)
        width = np.maximum(c_hi - c_lo + 2 * cfg.margin, cfg.min_width)
        c_mid = 0.5 * (c_hi + c_lo)
        w_open = g.opening(width)
        keep = (a_tip >= a_min + cfg.min_depth) & (n_enc >= cfg.min_enclosed)
        lowest = _lowest_box_z(pz + R[:, 2, 0] * a_tip + R[:, 2, 2] * c_mid, R, w_open, self.pregrasp_distance)
        keep &= lowest >= cfg.table_clearance - 1e-6
        return keep, reg, c_lo, c_hi, c_mid, width, w_open

    def _clear(self, u, ab, at, w_open, ok):
        """Stage 4: which frames have no valid (``ok``) neighbourhood point inside a finger, the palm or the
        wrist at opening ``w_open``, every box swept from the pre-grasp distance back to ``push`` forward; a
        point's coordinates relative to the grasp are u = a − a_tip along the approach, |b| across the
        fingers and |c − c_mid| along the closing axis (1.5 mm of tolerance)."""
        g = GRIPPER
        half_b, eps, back, push = g.finger_breadth / 2.0, 0.0015, self.pregrasp_distance, self.config.push
        hw = (w_open / 2)[:, None]
        hit = (u >= -g.finger_length - back - eps) & (u <= push + eps) & (ab <= half_b + eps) & \
            (at >= hw - eps) & (at <= hw + g.finger_thickness + eps)
        for box in (g.palm_box(), g.wrist_box()):
            lo = box.centre[0] - box.half[0] - back
            hi = box.centre[0] + box.half[0] + push
            hit |= (u >= lo - eps) & (u <= hi + eps) & (ab <= box.half[1] + eps) & (at <= box.half[2] + eps)
        return ~np.any(hit & ok, axis=1)

    def _score(self, R, origin, nz, reg, b, c, c_lo, c_hi, depth, cen, major, aniso, cam_pos):
        """Stage 5: the score in [0, 1] of each grasp (world rotation ``R``, world origin ``origin``), the
        weighted sum of the module docstring's step 6; ``nz`` holds the neighbourhood's normals · closing axis,
        ``depth`` = a_tip − a_min, ``cen``, ``major``, ``aniso`` the seed's object footprint."""
        half_b = GRIPPER.finger_breadth / 2.0
        xaxis, zaxis = R[:, :, 0], R[:, :, 2]
        al_hi = np.where(reg & (c >= (c_hi - 0.004)[:, None]), nz, -1.0).max(1)
        al_lo = np.where(reg & (c <= (c_lo + 0.004)[:, None]), -nz, -1.0).max(1)
        c0 = np.cos(2.0 * self.cone)
        antipodal = 0.5 * (np.clip((al_hi - c0) / (1.0 - c0), 0.0, 1.0) + np.clip((al_lo - c0) / (1.0 - c0), 0.0, 1.0))
        up = 0.5 * (1.0 - xaxis[:, 2])
        view = origin - cam_pos
        view /= np.linalg.norm(view, axis=1, keepdims=True)
        camside = 0.5 * (1.0 + np.sum(xaxis * view, axis=1))
        centre = 1.0 - np.clip(np.linalg.norm((origin - cen)[:, :2], axis=1) / 0.06, 0.0, 1.0)
        footprint = 1.0 - aniso * np.sum(zaxis[:, :2] * major, axis=1) ** 2
        depth = np.clip(depth / self.config.depth, 0.0, 1.0)
        cover = (np.where(reg, b, -np.inf).max(1) - np.where(reg, b, np.inf).min(1)) / (2 * half_b)
        cover = np.clip(cover, 0.0, 1.0)
        return (0.3 * antipodal + 0.15 * up + 0.15 * centre + 0.15 * footprint + 0.1 * depth + 0.05 * cover
                + 0.1 * camside)


def _strided_normals(depth: np.ndarray, K: np.ndarray, obj: np.ndarray, s: int
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Camera-frame normals, where they are defined and where coherent, on the ``s``-strided pixel grid of the
    planar ``depth`` (intrinsics ``K``), estimated at full resolution on the bounding box of the object pixels
    ``obj`` (the crop's origin aligned to the stride grid, ``K``'s principal point moved with it)."""
    h, w = depth.shape
    obj_s = obj[::s, ::s]
    rows, cols = np.flatnonzero(obj.any(1)), np.flatnonzero(obj.any(0))
    r0, c0 = max(rows[0] - 2, 0) // s * s, max(cols[0] - 2, 0) // s * s
    r1, c1 = min(rows[-1] + 3, h), min(cols[-1] + 3, w)
    Kc = K.copy()
    Kc[0, 2] -= c0
    Kc[1, 2] -= r0
    n, ok = estimate_normals(backproject(depth[r0:r1, c0:c1], Kc), obj[r0:r1, c0:c1])
    n, ok, coherent = _smooth_normals(n, ok)
    normals = np.zeros((*obj_s.shape, 3))
    has_normal = np.zeros(obj_s.shape, dtype=bool)
    smooth = np.zeros(obj_s.shape, dtype=bool)
    sub = (slice(r0 // s, r0 // s + n[::s, ::s].shape[0]), slice(c0 // s, c0 // s + n[::s, ::s].shape[1]))
    normals[sub], has_normal[sub], smooth[sub] = n[::s, ::s], ok[::s, ::s], coherent[::s, ::s]
    return normals, has_normal, smooth


def _seed_frames(n: np.ndarray, approaches: int, closings: int) -> tuple[np.ndarray, np.ndarray]:
    """The world grasp rotations (G, 3, 3) at seeds of world normals ``n`` (M, 3) and each one's seed index:
    family A closes along the normal (z = n) with ``approaches`` approach axes x over ±70° around the most
    downward one (kept where the normal is not near vertical, |n_z| < 0.85, and x_z < 0.3); family B approaches
    along −n (kept where −n_z < 0.3) with ``closings`` closing axes over 180°. Seed by seed, A before B."""
    e1, e2 = _perp_basis(n)
    ta = np.deg2rad(np.linspace(-70.0, 70.0, approaches)) if approaches > 1 else np.zeros(1)
    xa = np.cos(ta)[None, :, None] * e1[:, None] + np.sin(ta)[None, :, None] * e2[:, None]
    za = np.broadcast_to(n[:, None], xa.shape)
    ra = frame_from_xz(xa, za)
    ok_a = (np.abs(n[:, 2]) < 0.85)[:, None] & (xa[..., 2] < 0.3)
    xb = -n
    f1, f2 = _perp_basis(xb)
    tb = np.pi * np.arange(closings) / closings
    zb = np.cos(tb)[None, :, None] * f1[:, None] + np.sin(tb)[None, :, None] * f2[:, None]
    rb = frame_from_xz(np.broadcast_to(xb[:, None], zb.shape), zb)
    ok_b = np.broadcast_to((xb[:, 2] < 0.3)[:, None], zb.shape[:2])
    R = np.concatenate([ra, rb], axis=1).reshape(-1, 3, 3)
    seed_of = np.repeat(np.arange(len(n)), ra.shape[1] + rb.shape[1])
    alive = np.concatenate([ok_a, ok_b], axis=1).reshape(-1)
    return R[alive], seed_of[alive]


def _rows(keep: np.ndarray, *arrays: np.ndarray) -> list[np.ndarray]:
    """The rows ``keep`` of every array."""
    return [x[keep] for x in arrays]


def _extent(c: np.ndarray, mask: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``c`` (G, K) (closing-axis coordinates from the seed, seed at 0): the lowest and highest
    ``c`` of the ``mask`` points in the run of occupied ``_BIN`` bins around 0 that no empty stretch of at
    least ``_GAP`` interrupts, within ±``reach``. NaN where the run is not closed by a gap inside the range."""
    G = c.shape[0]
    nbins = round(2 * reach / _BIN)
    j0 = nbins // 2
    bi = np.floor((c + reach) / _BIN).astype(np.int64)
    inr = mask & (bi >= 0) & (bi < nbins)
    occ = np.zeros((G, nbins), dtype=bool)
    occ[np.nonzero(inr)[0], bi[inr]] = True
    occ[:, j0] = True
    gb = int(np.ceil(_GAP / _BIN))
    cs = np.concatenate([np.zeros((G, 1), dtype=np.int64), np.cumsum(occ, axis=1)], axis=1)
    j = np.arange(nbins)
    up = ((cs[:, np.minimum(j + gb, nbins)] - cs[:, j]) == 0) & (j > j0)  # bins j .. j+gb−1 empty
    dn = ((cs[:, j + 1] - cs[:, np.maximum(j - gb + 1, 0)]) == 0) & (j < j0)  # bins j−gb+1 .. j empty
    j_hi = np.argmax(up, axis=1) - 1  # −1 (an empty run) where no gap closes it
    j_lo = nbins - np.argmax(dn[:, ::-1], axis=1)  # nbins (empty) where none does
    seg = inr & (bi >= j_lo[:, None]) & (bi <= j_hi[:, None])
    c_lo = np.where(seg, c, np.inf).min(1)
    c_hi = np.where(seg, c, -np.inf).max(1)
    ok = np.isfinite(c_lo)
    return np.where(ok, c_lo, np.nan), np.where(ok, c_hi, np.nan)


def _lowest_box_z(oz: np.ndarray, R: np.ndarray, w_open: np.ndarray, back: float) -> np.ndarray:
    """Lowest world z of the gripper's fingers (at opening ``w_open``), palm and wrist, swept ``back`` (the
    pre-grasp distance) along −x, for grasps with origin height ``oz`` and rotations ``R`` (world)."""
    g = GRIPPER
    xz, yz, zz = R[:, 2, 0], R[:, 2, 1], R[:, 2, 2]
    lowest = np.full(len(R), np.inf)
    for box in (g.finger_box(1, 0.0), g.palm_box(), g.wrist_box()):
        ulo = box.centre[0] - box.half[0] - back
        uhi = box.centre[0] + box.half[0]
        reach = w_open / 2 + g.finger_thickness if box.name.endswith("finger") else box.half[2]
        low = oz + np.minimum(xz * ulo, xz * uhi) - np.abs(yz) * box.half[1] - np.abs(zz) * reach
        lowest = np.minimum(lowest, low)
    return lowest


def _footprints(points: np.ndarray, labels: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per component label: centroid (n, 3), unit major axis of the horizontal footprint (n, 2) and its
    anisotropy 1 − λ₂/λ₁ ∈ [0, 1] (0 for a round footprint), from the second moments of the points."""
    cnt = np.maximum(np.bincount(labels, minlength=n).astype(float), 1.0)
    cen = np.stack([np.bincount(labels, points[:, i], minlength=n) for i in range(3)], axis=1) / cnt[:, None]
    d = points[:, :2] - cen[labels, :2]
    sxx, syy, sxy = (np.bincount(labels, d[:, i] * d[:, j], minlength=n) / cnt for i, j in ((0, 0), (1, 1), (0, 1)))
    theta = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    mean, dev = 0.5 * (sxx + syy), np.hypot(0.5 * (sxx - syy), sxy)
    aniso = np.where(mean + dev > 0, 2.0 * dev / np.maximum(mean + dev, 1e-12), 0.0)
    return cen, np.stack([np.cos(theta), np.sin(theta)], axis=1), np.clip(aniso, 0.0, 1.0)


def _dedupe(poses: np.ndarray, distance: float, angle: float) -> np.ndarray:
    """Indices of ``poses`` (sorted best first) kept by greedy suppression of later poses within
    ``distance`` m and ``angle`` rad (approach axes within ``angle``, closing axes within it up to sign)."""
    n = len(poses)
    t, x, z = poses[:, :3, 3], poses[:, :3, 0], poses[:, :3, 2]
    ca = np.cos(angle)
    removed = np.zeros(n, dtype=bool)
    kept = []
    for i in range(n):
        if removed[i]:
            continue
        kept.append(i)
        near = (np.sum((t[i + 1:] - t[i]) ** 2, axis=1) < distance**2) & (x[i + 1:] @ x[i] > ca) & \
            (np.abs(z[i + 1:] @ z[i]) > ca)
        removed[i + 1:] |= near
    return np.array(kept, dtype=np.int64)
