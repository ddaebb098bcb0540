"""Decoding of KGN / KGNv2 prediction maps into camera-frame grasp candidates, following the
reference implementation.

Input: the dense maps of one image (numpy, float32, output resolution Ho × Wo, the head layout of
``kgn_bench.model.network``): ``hm`` (9, Ho, Wo) probabilities; ``reg`` (2, Ho, Wo); ``kpts`` (72, Ho, Wo), channel
8c + 2j + {0: x, 1: y}; ``width`` (9, Ho, Wo) m; ``scale`` (9, Ho, Wo) m for variants whose translation is
``scale``. ``M`` is the 2×3 image → output affine (see ``kgn_bench.model.targets``), ``K`` the 3×3
intrinsics of the original image.

Steps:

1. top-``top_k`` over all (bin, pixel) of ``hm`` (no peak NMS, as the reference), keep score ≥ threshold;
2. keypoints (L, R, TL, TR) = integer cell + the bin's 8 offsets; centre = cell + ``reg`` (output coords);
3. orientation consistency (optional): recompute the bin from the predicted L → R vector in output
   coordinates and drop the detection if it differs from its channel;
4. keypoints and centre → image pixels with ``M⁻¹``;
5. PnP: ``cv2.solvePnPGeneric`` with ``SOLVEPNP_IPPE`` on the box of side ``BOX_SIDE`` (L, R, TL, TR in the
   grasp frame), zero distortion; the first (lowest-error) solution gives ``T_cam_grasp``; solutions with
   t_z ≤ 0 or non-finite values are dropped. The reprojection error is the RMS Euclidean pixel distance
   ``sqrt(mean_j ‖π(T·P_j) − p_j‖²)`` of that solution over the 4 keypoints;
6. translation by ``variant.translation``: ``pnp`` keeps the metric t (fixed 0.1 m box); ``scale`` sets
   ``t ← ŝ · t/‖t‖`` with ŝ = ``scale[bin, y, x]``, or, with ``variant.scale_anchor == "depth"``,
   ŝ = d_obs(u_c, v_c) + ``scale[bin, y, x]`` (dropped if ŝ ≤ 0 or d_obs is undefined); ``depth`` sets
   ``‖t‖ = d_obs(u_c, v_c)``. d_obs is ``depth_anchor.observed_distance``: the Euclidean distance of the point
   of planar depth z on the ray through the predicted centre (u_c, v_c), with z the median of the valid
   (> 0, finite) depths in the 5×5 window around rint(u_c, v_c), the window clamped inside the image.

Widths are ``width[bin, y, x]`` clipped at 0; confidences are the heatmap scores.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from kgn_bench.grasp import keypoint_box
from kgn_bench.model.depth_anchor import DEPTH_WINDOW, depth_at, observed_distance
from kgn_bench.model.targets import NUM_BINS, apply_affine, invert_affine, orientation_bins
from kgn_bench.model.variants import BOX_SIDE, Variant
from kgn_bench.types import Candidates

__all__ = ["DEPTH_WINDOW", "DecodeConfig", "decode", "depth_at", "solve_box_pnp", "solve_box_pnp_batch"]

_BOX = keypoint_box(BOX_SIDE)


@dataclass(frozen=True)
class DecodeConfig:
    """``top_k`` detections at most (over all bins and pixels), kept if score ≥ ``score_threshold``;
    ``orientation_filter`` drops detections whose keypoint-derived bin differs from their channel."""

    top_k: int = 100
    score_threshold: float = 0.3
    orientation_filter: bool = True

    def __post_init__(self) -> None:
        if int(self.top_k) != self.top_k or self.top_k < 1:
            raise ValueError(f"top_k must be a positive integer, got {self.top_k}")
        if not 0.0 <= self.score_threshold <= 1.0:
            raise ValueError(f"score_threshold must be in [0, 1], got {self.score_threshold}")


def _check_maps(maps: dict, variant: Variant) -> dict[str, np.ndarray]:
    """The maps the variant needs as numpy arrays; ``ValueError`` on a missing key, a bad shape or NaN."""
    needed = {"hm": NUM_BINS, "reg": 2, "kpts": 8 * NUM_BINS, "width": NUM_BINS}
    if variant.translation == "scale":
        needed["scale"] = NUM_BINS
    missing = [k for k in needed if k not in maps]
    if missing:
        raise ValueError(f"prediction maps lack {', '.join(missing)} (variant {variant.name})")
    out = {k: np.asarray(maps[k]) for k in needed}
    hm_shape = out["hm"].shape
    if len(hm_shape) != 3 or hm_shape[0] != NUM_BINS or hm_shape[1] < 1 or hm_shape[2] < 1:
        raise ValueError(f"map hm must be ({NUM_BINS}, Ho, Wo), got {hm_shape}")
    for k, c in needed.items():
        if out[k].shape != (c, *hm_shape[1:]):
            raise ValueError(f"map {k} must be ({c}, {hm_shape[1]}, {hm_shape[2]}), got {out[k].shape}")
        if not np.issubdtype(out[k].dtype, np.floating) or not np.all(np.isfinite(out[k])):
            raise ValueError(f"map {k} must be finite floating point")
    return out


def _rotations_from_rotvecs(w: np.ndarray) -> np.ndarray:
    """Rodrigues' formula for a stack of rotation vectors (N, 3) (axis · angle, rad): (N, 3, 3)."""
    theta = np.linalg.norm(w, axis=1)
    safe = np.where(theta > 1e-12, theta, 1.0)
    k = w / safe[:, None]
    Kx = np.zeros((len(w), 3, 3))
    Kx[:, 0, 1], Kx[:, 0, 2], Kx[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    Kx -= np.swapaxes(Kx, 1, 2)
    s, c = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    return np.eye(3) + s * Kx + (1.0 - c) * (Kx @ Kx)


def solve_box_pnp_batch(
    image_points: np.ndarray, K: np.ndarray, side: float = BOX_SIDE
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IPPE poses of the box of side ``side`` (m) from image keypoints (N, 4, 2) px (L, R, TL, TR).

    Returns ``T_cam_grasp`` (N, 4, 4) of OpenCV's first (lowest-error) solution, the RMS Euclidean
    reprojection errors (N,) px and ``ok`` (N,): False where OpenCV fails or the solution is non-finite or
    has t_z ≤ 0 (those rows hold the identity and NaN).
    """
    box = _BOX if side == BOX_SIDE else keypoint_box(side)
    pts = np.ascontiguousarray(image_points, dtype=np.float64)
    n = len(pts)
    rvecs, tvecs = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    dist = np.zeros(4)
    for i in range(n):
        try:
            count, rv, tv, _ = cv2.solvePnPGeneric(box, pts[i], K, dist, flags=cv2.SOLVEPNP_IPPE)
        except cv2.error:
            continue
        if count >= 1:
            rvecs[i], tvecs[i] = rv[0].ravel(), tv[0].ravel()
    ok = np.all(np.isfinite(rvecs), axis=1) & np.all(np.isfinite(tvecs), axis=1)
    ok[ok] = tvecs[ok, 2] > 0.0
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[ok, :3, :3] = _rotations_from_rotvecs(rvecs[ok])
    poses[ok, :3, 3] = tvecs[ok]
    cam = np.einsum("nij,kj->nki", poses[:, :3, :3], box) + poses[:, None, :3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        proj = (cam @ K.T)[..., :2] / cam[..., 2:3]
        errors = np.sqrt(np.mean(np.sum((proj - pts) ** 2, axis=2), axis=1))
    errors[~ok] = np.nan
    return poses, errors, ok


def solve_box_pnp(image_points: np.ndarray, K: np.ndarray, side: float = BOX_SIDE) -> tuple[np.ndarray, float] | None:
    """``solve_box_pnp_batch`` for one detection: (``T_cam_grasp`` (4, 4), RMS error px), or None on failure."""
    poses, errors, ok = solve_box_pnp_batch(np.asarray(image_points, dtype=float)[None], K, side)
    return (poses[0], float(errors[0])) if ok[0] else None


def _top_k(hm: np.ndarray, k: int, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Flat indices and scores of the ``k`` highest entries ≥ ``threshold``, by descending score (ties by
    ascending index)."""
    flat = hm.reshape(-1)
    if k < flat.size:
        idx = np.argpartition(-flat, k - 1)[:k]
    else:
        idx = np.arange(flat.size)
    scores = flat[idx]
    order = np.lexsort((idx, -scores))
    idx, scores = idx[order], scores[order]
    keep = scores >= threshold
    return idx[keep], scores[keep].astype(float)


def decode(
    maps: dict,
    K: np.ndarray,
    M: np.ndarray,
    variant: Variant,
    config: DecodeConfig | None = None,
    depth: np.ndarray | None = None,
    timing: dict[str, float] | None = None,
) -> Candidates:
    """Grasp candidates (camera frame, ``T_cam_grasp``) of one image from its prediction maps.

    ``maps`` as in the module docstring, ``K`` 3×3 intrinsics, ``M`` 2×3 image → output affine, ``depth``
    (H, W) planar metres of the original image (needed when ``variant.needs_depth``, ignored otherwise).
    Candidate keypoints are the predicted image pixels in canonical order (L, R, TL, TR). ``timing``, if
    given, receives the seconds spent in PnP under ``"pnp"``.

    Steps: the ``top_k`` heatmap peaks over ``score_threshold`` (``_top_k``); their keypoints, centres,
    widths and scales in output pixels (``_read_peaks``); keypoints whose orientation bin is not the peak's
    dropped (``orientation_filter``); keypoints and centres mapped back to image pixels by M⁻¹; the box pose
    from IPPE PnP (``_solve_poses``); its translation rescaled to the predicted or observed distance
    (``_rescale_translations``); the candidates still kept returned.
    """
    config = config or DecodeConfig()
    m = _check_maps(maps, variant)
    K, M_inv, depth = _check_inputs(K, M, depth, variant)

    flat, scores = _top_k(m["hm"], int(config.top_k), config.score_threshold)
    if flat.size == 0:
        return Candidates.empty()
    c, kp_out, centre_out, widths, scale = _read_peaks(m, flat, variant)

    keep = np.ones(len(c), dtype=bool)
    if config.orientation_filter:
        keep &= orientation_bins(kp_out[:, 0], kp_out[:, 1]) == c
    kp_img = apply_affine(M_inv, kp_out)
    centre_img = apply_affine(M_inv, centre_out)

    poses, errors = _solve_poses(kp_img, K, keep, timing)
    if variant.translation != "pnp":
        _rescale_translations(poses, keep, variant, scale, depth, centre_img, K)

    if not np.any(keep):
        return Candidates.empty()
    return Candidates(
        poses=poses[keep],
        widths=widths[keep],
        confidences=scores[keep],
        reprojection_errors=errors[keep],
        keypoints=kp_img[keep],
    )


def _check_inputs(K: np.ndarray, M: np.ndarray, depth: np.ndarray | None, variant: Variant
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``K`` as a float 3×3 array, the output → image affine M⁻¹, and ``depth`` as an array (when ``variant``
    needs it); ``ValueError`` names a malformed one."""
    K = np.asarray(K, dtype=float)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        raise ValueError(f"K must be a finite 3×3 matrix, got shape {K.shape}")
    M_inv = invert_affine(M)
    if variant.needs_depth:
        if depth is None:
            raise ValueError(f"variant {variant.name} needs the depth image")
        depth = np.asarray(depth)
        if depth.ndim != 2 or depth.size == 0 or not np.issubdtype(depth.dtype, np.floating):
            raise ValueError(f"depth must be a non-empty (H, W) float image in metres, got {depth.shape} {depth.dtype}")
    return K, M_inv, depth


def _read_peaks(m: dict[str, np.ndarray], flat: np.ndarray, variant: Variant
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """At the peaks ``flat`` (indices into the (C, Ho, Wo) heatmap): the orientation bin c of each, its four
    keypoints (N, 4, 2) and centre (N, 2) in output pixels (the peak's cell (x, y) plus the predicted offsets),
    its width (m, clipped at 0) and, for a scale variant, its predicted distance (m; else None)."""
    _, ho, wo = m["hm"].shape
    c, rest = np.divmod(flat, ho * wo)
    y, x = np.divmod(rest, wo)
    cell = np.stack([x, y], axis=1).astype(float)
    offsets = m["kpts"][8 * c[:, None] + np.arange(8), y[:, None], x[:, None]].astype(float)
    kp_out = cell[:, None, :] + offsets.reshape(-1, 4, 2)
    centre_out = cell + m["reg"][:, y, x].T.astype(float)
    widths = np.maximum(m["width"][c, y, x].astype(float), 0.0)
    scale = m["scale"][c, y, x].astype(float) if variant.translation == "scale" else None
    return c, kp_out, centre_out, widths, scale


def _solve_poses(kp_img: np.ndarray, K: np.ndarray, keep: np.ndarray, timing: dict[str, float] | None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Box poses T_cam_box (N, 4, 4; identity where not solved) and reprojection errors (N; NaN where not
    solved) of the keypoints ``kp_img`` (image pixels) that ``keep`` holds, by IPPE PnP; clears ``keep``
    (in place) where PnP fails and puts its seconds in ``timing["pnp"]`` when given."""
    poses = np.repeat(np.eye(4)[None], len(kp_img), axis=0)
    errors = np.full(len(kp_img), np.nan)
    t0 = time.perf_counter()
    poses[keep], errors[keep], solved = solve_box_pnp_batch(kp_img[keep], K)
    if timing is not None:
        timing["pnp"] = time.perf_counter() - t0
    keep[keep] = solved
    return poses, errors


def _rescale_translations(poses: np.ndarray, keep: np.ndarray, variant: Variant, scale: np.ndarray | None,
                          depth: np.ndarray | None, centre_img: np.ndarray, K: np.ndarray) -> None:
    """In place: each kept pose's translation t scaled to the distance |t'| = d of ``variant`` (t' = t · d / |t|,
    0 where not kept): the observed distance of the centre pixel in ``depth`` (``depth`` variants), the
    predicted ``scale``, or scale + observed (a depth-anchored scale); ``keep`` cleared where that distance is
    not finite or not positive."""
    observed = np.full(len(keep), np.nan)
    if variant.needs_depth:
        observed[keep] = observed_distance(depth, centre_img[keep], K)
        keep &= np.isfinite(observed)
    if variant.translation == "depth":
        norm = observed
    else:
        norm = scale + observed if variant.scale_anchor == "depth" else scale
        keep &= norm > 0.0
    t = poses[:, :3, 3]
    t_len = np.linalg.norm(t, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        poses[:, :3, 3] = np.where(keep[:, None], t * (norm / t_len)[:, None], 0.0)
