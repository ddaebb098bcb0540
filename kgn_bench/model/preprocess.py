"""Network input of KGN / KGNv2: resize or warp RGB-D, standardise, pad; and the matching affine maps.

Pixel convention (OpenCV, as everywhere in the project): pixel ``(u, v)`` of an image has its centre at
the integer coordinates ``(u, v)``; its footprint is ``[u − ½, u + ½] × [v − ½, v + ½]``.

Affine maps (numpy float64, 2×3, ``[x', y'] = A @ [u, v, 1]``):

* ``A_in`` maps original-image pixels ``(u, v)`` to network-input pixels ``(x_in, y_in)``. It is exactly what
  the image operation does to pixel centres: the content at image pixel ``(u, v)`` lands at ``A_in @ (u, v, 1)``.
* ``M = output_affine(A_in, s) = A_in / s`` (every entry divided by the network's output stride s, 4 or 2)
  maps image pixels to output coordinates ``(x_o, y_o) = (x_in / s, y_in / s)``, the continuous coordinates of
  the output maps with output cell ``(i, j)`` at the integer point ``(j, i)``. No half-cell shift is applied:
  output cell ``(i, j)`` is the one whose integer coordinates are ``(x_in/s, y_in/s)``; what matters is only
  that training targets and decoding use the same ``M``, which they do when both come from this module.

Inference (``prepare``) resizes the full frame by ``input_scale`` σ with ``cv2.resize`` (σ = 0.5: 640×480 →
320×240) and pads right/bottom to a multiple of 32. For ``cv2.resize`` pixel centres move as
``u' = (u + ½)·s_x − ½`` with ``s_x = W'/W`` (and likewise for v), so
``A_in = [[s_x, 0, (s_x − 1)/2], [0, s_y, (s_y − 1)/2]]`` and, for σ = 0.5, ``M = [[1/8, 0, −1/16], [0, 1/8, −1/16]]``.

Training (``affine_for_crop`` + ``warp_inputs``) warps a crop of the full frame (any centre, size, aspect,
optional horizontal mirror) with ``cv2.warpAffine`` to a fixed input size. With the full-frame resize
affine, ``warp_inputs`` reproduces ``prepare`` exactly on the image region, so training and inference see
the same pixels.

Resampling: RGB is area-averaged (``INTER_AREA`` for the resize; for the warp, bilinear, which equals area
averaging at scale ½, preceded by a Gaussian pre-blur when the scale is below ½ so that zoomed-out crops
are not aliased). Depth is sampled with nearest neighbour through ``cv2.warpAffine`` in both paths (no
invented depths mixed across object edges): the source pixel nearest to the mapped centre, with OpenCV's
tie-breaking, which for σ = ½ is source pixel ``2u'`` — half a source pixel (1/16 output cell) from the
RGB centre, identically in training and inference.

Standardisation: channel ``k`` becomes ``(x_k − mean_k) / std_k`` with RGB in [0, 1] (uint8 / 255) and depth
in metres. The default constants are round values for our renders (the camera looks at the table centre
from 0.6–1.0 m at 30–90° elevation): RGB mean 0.5, std 0.25; depth mean 0.8 m, std 0.2 m. A check on 40
generated views gave RGB mean 0.53, std 0.19, and valid depth mean 0.77 m, std 0.16 m (1–99 % range
0.48–1.18 m), 8 % of the pixels invalid. The constants only need to bring the channels to order 1 (the
first convolution is followed by BatchNorm); the reference implementation's RGB std of 0.032 (fitted to its
synthetic renders) would blow real images up to ±20 and is not used.

Invalid depth (0 = no return) is set to the depth mean, i.e. standardised 0. Padding and the
out-of-image part of a crop are standardised 0 in all four channels too, so "no data" has one fixed
code everywhere, and it is the code the network meets during training (background beyond the table at
low elevation, crop borders) as well as at inference. A far-off sentinel (raw 0 m → −4) would mark holes
more distinctly but would put strong artificial edges around every hole and the padding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from kgn_bench.model.targets import OUTPUT_STRIDE, OUTPUT_STRIDES

__all__ = [
    "NUM_INPUT_CHANNELS",
    "InputConfig",
    "affine_for_crop",
    "full_frame_affine",
    "output_affine",
    "prepare",
    "standardize",
    "warp_images",
    "warp_inputs",
]

NUM_INPUT_CHANNELS = 4
"""Network input channels, in the order R, G, B, D."""


@dataclass(frozen=True)
class InputConfig:
    """How an RGB-D frame becomes the network input (see the module docstring for the maths).

    ``input_scale`` σ: full-frame resize factor at inference (0.5: 640×480 → 320×240).
    ``pad_multiple``: inputs are padded right/bottom to a multiple of this (the network's stride 32).
    ``mean`` / ``std``: standardisation constants for (R, G, B, D), RGB in [0, 1], depth in metres.
    """

    input_scale: float = 0.5
    pad_multiple: int = 32
    mean: tuple[float, float, float, float] = (0.5, 0.5, 0.5, 0.8)
    std: tuple[float, float, float, float] = (0.25, 0.25, 0.25, 0.2)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.input_scale) and 0.0 < self.input_scale <= 4.0):
            raise ValueError(f"input_scale must be in (0, 4], got {self.input_scale}")
        if self.pad_multiple <= 0 or self.pad_multiple % 32 != 0:
            raise ValueError(f"pad_multiple must be a positive multiple of 32, got {self.pad_multiple}")
        if len(self.mean) != NUM_INPUT_CHANNELS or len(self.std) != NUM_INPUT_CHANNELS:
            raise ValueError("mean and std need one value per channel (R, G, B, D)")
        if not all(math.isfinite(m) for m in self.mean) or not all(s > 0 and math.isfinite(s) for s in self.std):
            raise ValueError("mean must be finite and std positive")


def _check_rgbd(rgb: np.ndarray, depth: np.ndarray) -> None:
    """One-line ``ValueError`` for malformed RGB-D input (see ``prepare``)."""
    if not isinstance(rgb, np.ndarray) or rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        raise ValueError(f"rgb must be an (H, W, 3) uint8 array, got {getattr(rgb, 'shape', None)} "
                         f"{getattr(rgb, 'dtype', type(rgb).__name__)}")
    if not isinstance(depth, np.ndarray) or depth.shape != rgb.shape[:2]:
        raise ValueError(f"depth must be an {rgb.shape[:2]} array matching rgb, got {getattr(depth, 'shape', None)}")
    if not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(f"depth must be float metres, got dtype {depth.dtype}")
    if rgb.shape[0] < 2 or rgb.shape[1] < 2:
        raise ValueError(f"image too small: {rgb.shape[:2]}")
    if not np.all(np.isfinite(depth)):
        raise ValueError("depth contains NaN or inf (use 0 for no measurement)")
    if np.any(depth < 0):
        raise ValueError("depth contains negative values")
    if not np.any(depth > 0):
        raise ValueError("depth has no valid (positive) pixel")


def _check_affine(A: np.ndarray) -> np.ndarray:
    A = np.asarray(A, dtype=np.float64)
    if A.shape != (2, 3) or not np.all(np.isfinite(A)):
        raise ValueError(f"affine must be a finite 2×3 matrix, got shape {A.shape}")
    if abs(np.linalg.det(A[:, :2])) < 1e-12:
        raise ValueError("affine is singular")
    return A


def _check_size(size: tuple[int, int], name: str) -> tuple[int, int]:
    if len(size) != 2 or int(size[0]) <= 0 or int(size[1]) <= 0:
        raise ValueError(f"{name} must be a positive (width, height), got {size}")
    return int(size[0]), int(size[1])


def output_affine(A_in: np.ndarray, stride: int = OUTPUT_STRIDE) -> np.ndarray:
    """Image pixels → output coordinates: ``M = A_in / stride`` (2×3 float64), ``x_o = x_in / s`` for the
    network's output stride ``s`` (4 or 2); ``ValueError`` for another stride."""
    if stride not in OUTPUT_STRIDES:
        raise ValueError(f"output stride must be one of {OUTPUT_STRIDES}, got {stride}")
    return _check_affine(A_in) / stride


def full_frame_affine(image_size: tuple[int, int], config: InputConfig = InputConfig()) -> np.ndarray:
    """``A_in`` (2×3) of the inference resize of a (width, height) frame by ``config.input_scale``.

    The resized size is ``(round(W·σ), round(H·σ))`` and the per-axis factors are the exact ratios
    ``s_x = W'/W``, ``s_y = H'/H``; pixel centres move as ``u' = (u + ½)·s_x − ½`` (``cv2.resize``).
    """
    w, h = _check_size(image_size, "image_size")
    ws, hs = _resized_size(w, h, config.input_scale)
    sx, sy = ws / w, hs / h
    return np.array([[sx, 0.0, 0.5 * (sx - 1.0)], [0.0, sy, 0.5 * (sy - 1.0)]])


def _resized_size(w: int, h: int, scale: float) -> tuple[int, int]:
    ws, hs = round(w * scale), round(h * scale)
    if ws < 1 or hs < 1:
        raise ValueError(f"input_scale {scale} shrinks a {w}×{h} frame to nothing")
    return ws, hs


def affine_for_crop(
    center_uv: tuple[float, float] | np.ndarray,
    crop_size: float | tuple[float, float],
    input_size: tuple[int, int],
    flip: bool = False,
) -> np.ndarray:
    """``A_in`` (2×3) that maps an image crop onto a network input of ``input_size`` = (width, height).

    The crop is the axis-aligned rectangle of ``crop_size`` (a side for a square, or (width, height)) in
    image pixels centred at ``center_uv`` (image px, may lie anywhere; parts outside the image become the
    neutral border). Its outer edges map onto the input's outer edges (pixel footprints included):
    ``x_in = (u − c_u)·W_in/w_crop + (W_in − 1)/2``, ``y_in = (v − c_v)·H_in/h_crop + (H_in − 1)/2``.
    The whole W×H frame is the crop centred at ((W − 1)/2, (H − 1)/2) of size (W, H); with input size
    (σW, σH) that is ``full_frame_affine``. A crop smaller than ``W_in/σ`` zooms in relative to the
    inference resize, a larger one zooms out.
    ``flip`` mirrors the input horizontally, ``x_in ← (W_in − 1) − x_in`` (exactly ``cv2.flip(·, 1)`` of the
    unflipped input). After a flip the image's left/right are swapped: keypoint targets must be
    re-canonicalised (L↔R, TL↔TR) by the target code, which works in output coordinates from ``M``.
    """
    w_in, h_in = _check_size(input_size, "input_size")
    cw, ch = (float(crop_size), float(crop_size)) if np.isscalar(crop_size) else (float(c) for c in crop_size)
    if not (cw > 0 and ch > 0 and math.isfinite(cw) and math.isfinite(ch)):
        raise ValueError(f"crop_size must be positive and finite, got {crop_size}")
    cu, cv = (float(c) for c in np.asarray(center_uv, dtype=float).reshape(2))
    if not (math.isfinite(cu) and math.isfinite(cv)):
        raise ValueError(f"center_uv must be finite, got {center_uv}")
    sx, sy = w_in / cw, h_in / ch
    A = np.array([[sx, 0.0, (w_in - 1) / 2 - sx * cu], [0.0, sy, (h_in - 1) / 2 - sy * cv]])
    if flip:
        A[0] = -A[0]
        A[0, 2] += w_in - 1
    return A


def _prefilter_sigmas(A: np.ndarray) -> tuple[float, float]:
    """Gaussian pre-blur σ (image px, along u and v) that turns bilinear sampling into ≈ area averaging.

    Bilinear sampling at scale ½ averages exactly the 2×2 source footprint; an area filter at scale
    s < ½ averages a 1/s-wide box, whose variance ``(1/s)²/12`` exceeds that of the 2-px box by
    ``((1/s)² − 4)/12``: that difference is the pre-blur variance (0 for s ≥ ½).
    """
    sx = math.hypot(A[0, 0], A[1, 0])  # input px moved per image px along u
    sy = math.hypot(A[0, 1], A[1, 1])
    return tuple(math.sqrt(max(0.0, (1.0 / s) ** 2 - 4.0) / 12.0) for s in (sx, sy))


def warp_images(
    rgb: np.ndarray,
    depth: np.ndarray,
    A_in: np.ndarray,
    input_size: tuple[int, int],
    config: InputConfig = InputConfig(),
) -> tuple[np.ndarray, np.ndarray]:
    """Warp RGB (uint8) and depth (metres) by ``A_in`` to ``input_size`` = (width, height), unstandardised.

    RGB: bilinear in float (with the anti-alias pre-blur of ``_prefilter_sigmas``), border = the RGB mean
    (so it standardises to 0). Depth: nearest neighbour, border 0 (invalid). Returns ``(rgb (H, W, 3)
    float32 in [0, 255], depth (H, W) float32 metres)`` so that augmentations (colour, depth noise) can run
    before ``standardize``.
    """
    _check_rgbd(rgb, depth)
    A = _check_affine(A_in)
    size = _check_size(input_size, "input_size")
    sig_u, sig_v = _prefilter_sigmas(A)
    src = rgb.astype(np.float32)
    if sig_u > 0.0 or sig_v > 0.0:
        src = cv2.GaussianBlur(src, (0, 0), sigmaX=max(sig_u, 1e-3), sigmaY=max(sig_v, 1e-3))
    border = tuple(255.0 * m for m in config.mean[:3])
    rgb_w = cv2.warpAffine(src, A, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=border)
    depth_w = cv2.warpAffine(
        depth.astype(np.float32, copy=False), A, size, flags=cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT, borderValue=0.0,
    )
    return rgb_w, depth_w


def standardize(rgb: np.ndarray, depth: np.ndarray, config: InputConfig = InputConfig()) -> np.ndarray:
    """(4, H, W) float32: ``(rgb/255 − mean)/std`` for R, G, B and ``(d − mean_D)/std_D`` for valid depth,
    0 where depth is invalid (``d ≤ 0``). ``rgb`` (H, W, 3) uint8 or float in [0, 255]; ``depth`` (H, W) metres."""
    mean = np.asarray(config.mean, dtype=np.float32)
    std = np.asarray(config.std, dtype=np.float32)
    out = np.empty((NUM_INPUT_CHANNELS, *depth.shape), dtype=np.float32)
    rgb_f = np.asarray(rgb, dtype=np.float32)
    for k in range(3):
        out[k] = (rgb_f[..., k] * (1.0 / 255.0) - mean[k]) / std[k]
    d = np.asarray(depth, dtype=np.float32)
    out[3] = np.where(d > 0, (d - mean[3]) / std[3], 0.0)
    return out


def warp_inputs(
    rgb: np.ndarray,
    depth: np.ndarray,
    A_in: np.ndarray,
    input_size: tuple[int, int],
    config: InputConfig = InputConfig(),
) -> torch.Tensor:
    """Standardised network input (4, H, W) float32 tensor of the crop ``A_in`` (``warp_images`` then
    ``standardize``); the image → output map is ``output_affine(A_in)``."""
    rgb_w, depth_w = warp_images(rgb, depth, A_in, input_size, config)
    return torch.from_numpy(standardize(rgb_w, depth_w, config))


def prepare(
    rgb: np.ndarray, depth: np.ndarray, config: InputConfig = InputConfig(), stride: int = OUTPUT_STRIDE
) -> tuple[torch.Tensor, np.ndarray, tuple[int, int]]:
    """Inference input of one full frame.

    ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float metres (planar z, 0 = no measurement). The frame is
    resized by σ = ``config.input_scale`` (RGB ``INTER_AREA``; depth nearest neighbour through
    ``cv2.warpAffine`` with the same affine, see the module docstring), standardised, and padded with 0
    right/bottom to a multiple of ``config.pad_multiple``.

    Returns ``(x, M, (Ho, Wo))``: ``x`` (4, Hp, Wp) float32 tensor; ``M`` (2×3 float64) maps image pixels to
    the output coordinates of a network of output stride ``stride`` s (σ = ½, s = 4: ``x_o = u/8 − 1/16``);
    ``(Ho, Wo) = (⌈H'/s⌉, ⌈W'/s⌉)`` is the part of the (Hp/s, Wp/s) output maps that covers the resized H'×W'
    image (the rest covers padding).
    ``ValueError`` (one line) for a wrong shape or dtype, NaN/inf or negative depth, or no valid depth.
    """
    _check_rgbd(rgb, depth)
    h, w = depth.shape
    ws, hs = _resized_size(w, h, config.input_scale)
    A = full_frame_affine((w, h), config)
    rgb_s = cv2.resize(rgb, (ws, hs), interpolation=cv2.INTER_AREA)
    depth_s = cv2.warpAffine(depth.astype(np.float32, copy=False), A, (ws, hs), flags=cv2.INTER_NEAREST,
                             borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    m = config.pad_multiple
    hp, wp = -(-hs // m) * m, -(-ws // m) * m
    x = np.zeros((NUM_INPUT_CHANNELS, hp, wp), dtype=np.float32)
    x[:, :hs, :ws] = standardize(rgb_s, depth_s, config)
    M = output_affine(A, stride)
    return torch.from_numpy(x), M, (-(-hs // stride), -(-ws // stride))
