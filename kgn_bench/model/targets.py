"""Training targets of KGN / KGNv2 from ground-truth grasps, built as in the reference implementation.

Frames and units. Grasp poses are ``T_cam_grasp`` (4×4, OpenCV camera frame, metres; grasp frame:
origin at the fingertip midpoint, +x the approach, z the closing axis, ``kgn_bench.grasp``). Image pixels
``(u, v)`` follow OpenCV (pixel centres at integers). Output coordinates ``(x_o, y_o)`` are continuous pixel
coordinates of the output maps (stride 4 or 2), reached from image pixels by the 2×3 affine ``M``:
``[x_o, y_o] = M @ [u, v, 1]`` (resize, crop, zoom and horizontal flip).

Per grasp, in order:

1. box side ``a = variant.box_sides(‖t_cam‖)``; the 4 box keypoints (L, R, TL, TR) and the grasp origin
   (the centre) are projected with ``K`` and mapped to output coordinates with ``M``;
2. left/right canonicalisation in output coordinates: if ``x_L > x_R`` the pose becomes
   ``T · diag(1, −1, −1, 1)`` and the keypoints are re-ordered (R, L, TR, TL), which is exactly the
   projection of the turned pose;
3. orientation bin ``c = ⌊(θ + π/2)/(π/9)⌋`` clamped to [0, 8], ``θ = atan2(y_R − y_L, x_R − x_L)``;
4. the grasp is dropped if any of the 5 points is behind the camera (z ≤ 0) or outside
   ``[0, Wo) × [0, Ho)``; then at most one grasp per (cell, bin) and the first ``MAX_GRASPS`` remaining
   grasps take the slots (grasps without a slot draw nothing), both in the order of the ``assignment``
   rule: ``"first"`` (the reference) keeps the input order, so the first grasp of a (cell, bin) wins;
   ``"frontal"`` orders the grasps by descending ``cos ∠(x̂_grasp, t̂)``, the alignment of the approach axis
   with the viewing ray of the grasp origin, so the grasp approached most nearly from the camera wins. Where
   several grasps share a (cell, bin) the network can only regress one of them; "frontal" makes the
   choice a function of what the image shows, where "first" depends on the order in which a shape lists
   its grasp family, which the image does not show (a cylinder's family starts at an invisible angle);
5. heatmap: a 3×3 Gaussian (σ = 0.5: 1 at the integer cell, e^−2 at edges, e^−4 at corners, clipped at
   the map border) in channel ``c``, combined by element-wise maximum; ``heatmap_radius`` r > 1 widens it
   to (2r+1)×(2r+1) cells with σ = (2r+1)/6 (r = 2 at stride 2 covers about the image area of r = 1 at
   stride 4).

Target dict (the input of ``kgn_bench.model.losses``), ``S = MAX_GRASPS`` slots: ``hm`` (9, Ho, Wo)
float32; ``ind`` (S,) int64 ``= y_int·Wo + x_int``; ``mask`` (S,) float32; ``bin`` (S,) int64; ``reg``
(S, 2) float32 ``= centre − cell``; ``kpts`` (S, 8) float32 keypoint offsets from the cell (L, R, TL, TR;
x, y interleaved, output px); ``width`` (S,) float32 metres; ``scale`` (S,) float32 ``= ‖t_cam‖`` metres, or,
for a depth-anchored scale head (``variant.scale_anchor == "depth"``), the residual ``‖t_cam‖ − d_obs`` to
the observed distance along the ray of the grasp's image centre (``kgn_bench.model.depth_anchor``; residual
0 where the depth image has no valid value near that centre).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kgn_bench.grasp import FLIP_X180, keypoints_in_frame
from kgn_bench.model.depth_anchor import observed_distance
from kgn_bench.model.variants import Variant

__all__ = [
    "ASSIGNMENTS",
    "MAX_GRASPS",
    "NUM_BINS",
    "OUTPUT_STRIDE",
    "OUTPUT_STRIDES",
    "AssignedGrasps",
    "apply_affine",
    "assign_grasps",
    "encode_targets",
    "invert_affine",
    "orientation_bins",
    "project_keypoints",
    "render_heatmap",
    "targets_to_maps",
]

NUM_BINS = 9
"""Orientation bins of 20° over [−90°, 90°)."""
OUTPUT_STRIDE = 4
"""The default output stride: output maps have 1/4 of the network input resolution (the reference's)."""
OUTPUT_STRIDES = (2, 4)
"""The output strides the network offers (``NetworkConfig.output_stride``)."""
MAX_GRASPS = 300
"""Target slots per image."""

ASSIGNMENTS = ("first", "frontal")
"""Rules for which grasp takes a (cell, bin) and the slots (module docstring, step 4)."""

_SWAP = np.array([1, 0, 3, 2])
"""Keypoint re-ordering of the 180°-turned grasp: (L, R, TL, TR) → (R, L, TR, TL)."""


def orientation_bins(left_xy: np.ndarray, right_xy: np.ndarray) -> np.ndarray:
    """Orientation bin of the L→R vector, (N,) int64, from L and R points (N, 2) (image axes, y down).

    ``θ = atan2(y_R − y_L, x_R − x_L)``, ``bin = ⌊(θ + π/2)/(π/9)⌋`` clamped to [0, 8]: horizontal → 4,
    ±45° → 6 / 2, +90° → 8, −90° → 0. Angles outside [−90°, 90°] clamp to the nearest end bin.
    """
    d = np.asarray(right_xy, dtype=float) - np.asarray(left_xy, dtype=float)
    theta = np.arctan2(d[..., 1], d[..., 0])
    bins = np.floor((theta + np.pi / 2.0) / (np.pi / NUM_BINS)).astype(np.int64)
    return np.clip(bins, 0, NUM_BINS - 1)


def apply_affine(M: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``M @ [x, y, 1]`` for points (..., 2) and a 2×3 affine ``M``: (..., 2)."""
    return points @ M[:, :2].T + M[:, 2]


def invert_affine(M: np.ndarray) -> np.ndarray:
    """The 2×3 affine that undoes ``M``; ``ValueError`` if ``M`` is singular or not 2×3 finite."""
    M = np.asarray(M, dtype=float)
    if M.shape != (2, 3) or not np.all(np.isfinite(M)):
        raise ValueError(f"affine M must be a finite 2×3 matrix, got shape {M.shape}")
    A = M[:, :2]
    if abs(np.linalg.det(A)) < 1e-12:
        raise ValueError("affine M is singular")
    Ai = np.linalg.inv(A)
    return np.concatenate([Ai, -(Ai @ M[:, 2])[:, None]], axis=1)


def project_keypoints(poses_cam: np.ndarray, K: np.ndarray, sides: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Image projections (px) of the box keypoints and the grasp origins of grasps ``T_cam_grasp``.

    ``poses_cam`` (N, 4, 4), ``K`` 3×3, ``sides`` (N,) box sides a in metres. Returns keypoints (N, 4, 2) in
    the order L, R, TL, TR and centres (N, 2). A point with camera z ≤ 0 projects to NaN.
    """
    pts = np.concatenate([keypoints_in_frame(poses_cam, sides), poses_cam[:, None, :3, 3]], axis=1)
    z = pts[..., 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (pts @ K.T)[..., :2] / z
    uv = np.where(z > 0.0, uv, np.nan)
    return uv[:, :4], uv[:, 4]


@dataclass(frozen=True)
class AssignedGrasps:
    """The grasps that received a target slot, in slot order (K ≤ ``MAX_GRASPS``).

    ``indices`` (K,) positions in the input arrays; ``poses`` (K, 4, 4) canonical ``T_cam_grasp`` (the input
    pose or the input pose · diag(1, −1, −1, 1)); ``flipped`` (K,) which were turned; ``bins`` (K,);
    ``cells`` (K, 2) integer (x, y) output cells; ``centres`` (K, 2) and ``keypoints`` (K, 4, 2) output
    coordinates (canonical order L, R, TL, TR); ``widths`` (K,) m; ``scales`` (K,) = ‖t_cam‖ m;
    ``sides`` (K,) box sides m.
    """

    indices: np.ndarray
    poses: np.ndarray
    flipped: np.ndarray
    bins: np.ndarray
    cells: np.ndarray
    centres: np.ndarray
    keypoints: np.ndarray
    widths: np.ndarray
    scales: np.ndarray
    sides: np.ndarray

    def __len__(self) -> int:
        return int(self.indices.shape[0])


def _check_out_shape(out_shape: tuple[int, int]) -> tuple[int, int]:
    if len(out_shape) != 2 or not all(int(s) == s and s > 0 for s in out_shape):
        raise ValueError(f"out_shape must be two positive integers (Ho, Wo), got {out_shape}")
    return int(out_shape[0]), int(out_shape[1])


def assign_grasps(
    poses_cam: np.ndarray,
    widths: np.ndarray,
    K: np.ndarray,
    M: np.ndarray,
    out_shape: tuple[int, int],
    variant: Variant,
    assignment: str = "first",
) -> AssignedGrasps:
    """Steps 1–4 of the module docstring: which grasps become targets, canonicalised, with their geometry.

    ``poses_cam`` (N, 4, 4) ``T_cam_grasp``, ``widths`` (N,) m, ``K`` 3×3 intrinsics of the image, ``M`` 2×3
    image → output affine, ``out_shape`` (Ho, Wo), ``assignment`` one of ``ASSIGNMENTS``.
    """
    poses_cam, widths, K, M = _check_grasp_inputs(poses_cam, widths, K, M, assignment)
    ho, wo = _check_out_shape(out_shape)
    n = poses_cam.shape[0] if poses_cam.ndim == 3 else -1
    if poses_cam.shape != (n, 4, 4) or widths.shape != (n,):
        raise ValueError(f"poses must be (N, 4, 4) with widths (N,), got {poses_cam.shape} and {widths.shape}")
    if not (np.all(np.isfinite(poses_cam)) and np.all(np.isfinite(widths))):
        raise ValueError("grasp poses and widths must be finite")
    if K.shape != (3, 3) or not np.all(np.isfinite(K)):
        raise ValueError(f"K must be a finite 3×3 matrix, got shape {K.shape}")
    invert_affine(M)  # validates M

    scales = np.linalg.norm(poses_cam[:, :3, 3], axis=1)
    sides = variant.box_sides(scales)
    kp, ct = _output_keypoints(poses_cam, K, M, sides)
    flipped = kp[:, 0, 0] > kp[:, 1, 0]
    kp = np.where(flipped[:, None, None], kp[:, _SWAP], kp)
    poses = np.where(flipped[:, None, None], poses_cam @ FLIP_X180, poses_cam)
    inside, cells, bins = _cells_and_bins(kp, ct, ho, wo)
    keep = _one_per_cell(np.flatnonzero(inside), poses_cam, bins, cells, ho, wo, assignment)
    return AssignedGrasps(
        indices=keep.astype(np.int64),
        poses=poses[keep],
        flipped=flipped[keep],
        bins=bins[keep],
        cells=cells[keep],
        centres=ct[keep],
        keypoints=kp[keep],
        widths=widths[keep],
        scales=scales[keep],
        sides=sides[keep],
    )


def _check_grasp_inputs(poses_cam, widths, K, M, assignment: str
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The inputs of ``assign_grasps`` as float arrays; ``ValueError`` for an unknown ``assignment``."""
    if assignment not in ASSIGNMENTS:
        raise ValueError(f"unknown assignment {assignment!r} (known: {', '.join(ASSIGNMENTS)})")
    return (np.asarray(poses_cam, dtype=float), np.asarray(widths, dtype=float), np.asarray(K, dtype=float),
            np.asarray(M, dtype=float))


def _output_keypoints(poses_cam: np.ndarray, K: np.ndarray, M: np.ndarray, sides: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The four keypoints (N, 4, 2) and the centre (N, 2) of each grasp's box of side ``sides`` in output
    pixels: projected by ``K`` into the image (``project_keypoints``), then mapped by the affine ``M``; NaN
    where the side is not positive (a scale-normalised box of a grasp at the camera centre has no size)."""
    n = len(poses_cam)
    positive = sides > 0.0
    kp_img, ct_img = project_keypoints(poses_cam[positive], K, sides[positive])
    kp = np.full((n, 4, 2), np.nan)
    ct = np.full((n, 2), np.nan)
    kp[positive] = apply_affine(M, kp_img)
    ct[positive] = apply_affine(M, ct_img)
    return kp, ct


def _cells_and_bins(kp: np.ndarray, ct: np.ndarray, ho: int, wo: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Which grasps have their keypoints ``kp`` and centre ``ct`` (output pixels) all inside the (``ho``,
    ``wo``) output (NaN, behind the camera, compares False: dropped too), their centre cells (x, y) = ⌊ct⌋
    and orientation bins (0 where outside)."""
    n = len(kp)
    pts = np.concatenate([kp, ct[:, None]], axis=1)
    inside = np.all((pts[..., 0] >= 0.0) & (pts[..., 0] < wo) & (pts[..., 1] >= 0.0) & (pts[..., 1] < ho), axis=1)
    cells = np.zeros((n, 2), dtype=np.int64)
    cells[inside] = np.floor(ct[inside]).astype(np.int64)
    # The bin is computed from the keypoints as the decoder will see them (cell + float32 offset), so an
    # angle on a bin boundary cannot land in different bins on the two sides of the round trip.
    kp_q = cells[:, None, :] + (kp - cells[:, None, :]).astype(np.float32).astype(float)
    bins = np.zeros(n, dtype=np.int64)
    bins[inside] = orientation_bins(kp_q[inside, 0], kp_q[inside, 1])
    return inside, cells, bins


def _one_per_cell(candidates: np.ndarray, poses_cam: np.ndarray, bins: np.ndarray, cells: np.ndarray, ho: int,
                  wo: int, assignment: str) -> np.ndarray:
    """The indices kept of the ``candidates``: the first in each (bin, cell) target, in the order of the
    labels ("first") or most frontal first ("frontal": the approach axis x against the camera ray to the
    grasp, x · t / |t|, highest first), at most ``MAX_GRASPS``, in the order of their first appearance."""
    if assignment == "frontal" and len(candidates):
        t = poses_cam[candidates, :3, 3]
        alignment = np.einsum("ni,ni->n", poses_cam[candidates, :3, 0], t) / np.linalg.norm(t, axis=1)
        candidates = candidates[np.argsort(-alignment, kind="stable")]
    key = (bins[candidates] * ho + cells[candidates, 1]) * wo + cells[candidates, 0]
    _, first = np.unique(key, return_index=True)
    return candidates[np.sort(first)][:MAX_GRASPS]


def render_heatmap(cells: np.ndarray, bins: np.ndarray, out_shape: tuple[int, int], radius: int = 1) -> np.ndarray:
    """(9, Ho, Wo) float32 heatmap: a (2r+1)×(2r+1) Gaussian of σ = (2r+1)/6 (CenterNet's rule; ``radius``
    r = 1, the reference: σ = 0.5, values 1, e^−2, e^−4) at each integer cell (x, y) (K, 2) in channel ``bins``
    (K,), clipped at the map border, combined by element-wise maximum."""
    ho, wo = _check_out_shape(out_shape)
    if radius < 1:
        raise ValueError(f"radius must be at least 1, got {radius}")
    sigma = (2 * radius + 1) / 6.0
    hm = np.zeros(NUM_BINS * ho * wo, dtype=np.float32)
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    bins = np.asarray(bins, dtype=np.int64).reshape(-1)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            x, y = cells[:, 0] + dx, cells[:, 1] + dy
            ok = (x >= 0) & (x < wo) & (y >= 0) & (y < ho)
            value = np.float32(np.exp(-(dx * dx + dy * dy) / (2.0 * sigma**2)))
            np.maximum.at(hm, (bins[ok] * ho + y[ok]) * wo + x[ok], value)
    return hm.reshape(NUM_BINS, ho, wo)


def encode_targets(
    poses_cam: np.ndarray,
    widths: np.ndarray,
    K: np.ndarray,
    M: np.ndarray,
    out_shape: tuple[int, int],
    variant: Variant,
    depth: np.ndarray | None = None,
    assignment: str = "first",
    heatmap_radius: int = 1,
) -> dict[str, np.ndarray]:
    """Training targets of one image (format in the module docstring) from its ground-truth grasps.

    Arguments as in ``assign_grasps``, ``depth`` (H, W) planar metres of the image (needed, and only read,
    when ``variant.scale_anchor == "depth"``) and ``heatmap_radius`` (``render_heatmap``); use
    ``assign_grasps`` to learn which grasps were kept.
    """
    ho, wo = _check_out_shape(out_shape)
    a = assign_grasps(poses_cam, widths, K, M, out_shape, variant, assignment)
    scales = a.scales
    if variant.scale_anchor == "depth":
        if depth is None:
            raise ValueError(f"a depth-anchored scale ({variant.name}) needs the depth image")
        _, centres_img = project_keypoints(a.poses, np.asarray(K, dtype=float), a.sides)
        residual = a.scales - observed_distance(np.asarray(depth), centres_img, np.asarray(K, dtype=float))
        scales = np.where(np.isfinite(residual), residual, 0.0)
    k = len(a)
    targets = {
        "hm": render_heatmap(a.cells, a.bins, (ho, wo), heatmap_radius),
        "ind": np.zeros(MAX_GRASPS, dtype=np.int64),
        "mask": np.zeros(MAX_GRASPS, dtype=np.float32),
        "bin": np.zeros(MAX_GRASPS, dtype=np.int64),
        "reg": np.zeros((MAX_GRASPS, 2), dtype=np.float32),
        "kpts": np.zeros((MAX_GRASPS, 8), dtype=np.float32),
        "width": np.zeros(MAX_GRASPS, dtype=np.float32),
        "scale": np.zeros(MAX_GRASPS, dtype=np.float32),
    }
    targets["ind"][:k] = a.cells[:, 1] * wo + a.cells[:, 0]
    targets["mask"][:k] = 1.0
    targets["bin"][:k] = a.bins
    targets["reg"][:k] = a.centres - a.cells
    targets["kpts"][:k] = (a.keypoints - a.cells[:, None, :]).reshape(k, 8)
    targets["width"][:k] = a.widths
    targets["scale"][:k] = scales
    return targets


def targets_to_maps(targets: dict[str, np.ndarray], variant: Variant) -> dict[str, np.ndarray]:
    """Dense prediction maps (float32, the decoder's input format) that a perfect network would output.

    ``hm`` is the target heatmap; at each used slot's cell, ``reg`` gets the slot's offset and the slot's
    bin channels of ``kpts`` (8c … 8c+7), ``width`` and (variants with a scale branch) ``scale`` get its
    values. ``reg`` has no bin channel: where grasps of different bins share a cell, the first slot's
    ``reg`` is written.
    """
    hm = np.asarray(targets["hm"], dtype=np.float32)
    if hm.ndim != 3 or hm.shape[0] != NUM_BINS:
        raise ValueError(f"target hm must be ({NUM_BINS}, Ho, Wo), got {hm.shape}")
    _, ho, wo = hm.shape
    used = np.flatnonzero(np.asarray(targets["mask"]) > 0)
    ind, c = np.asarray(targets["ind"])[used], np.asarray(targets["bin"])[used]
    y, x = ind // wo, ind % wo
    _, first_at_cell = np.unique(ind, return_index=True)
    maps = {
        "hm": hm.copy(),
        "reg": np.zeros((2, ho, wo), dtype=np.float32),
        "kpts": np.zeros((8 * NUM_BINS, ho, wo), dtype=np.float32),
        "width": np.zeros((NUM_BINS, ho, wo), dtype=np.float32),
    }
    r = used[first_at_cell]
    maps["reg"][:, y[first_at_cell], x[first_at_cell]] = np.asarray(targets["reg"])[r].T
    channels = 8 * c[:, None] + np.arange(8)
    maps["kpts"][channels, y[:, None], x[:, None]] = np.asarray(targets["kpts"])[used]
    maps["width"][c, y, x] = np.asarray(targets["width"])[used]
    if variant.scale_branch:
        maps["scale"] = np.zeros((NUM_BINS, ho, wo), dtype=np.float32)
        maps["scale"][c, y, x] = np.asarray(targets["scale"])[used]
    return maps
