"""Degradations of rendered planar depth: a RealSense-D435-like stereo model (``DepthNoise``, after Intel's D400
stereo depth and noise model) and GIGA's "dex" model (``DexNoise``, below).

The D435 measures depth by stereo matching between a left (reference) and a right infrared imager a baseline
``B`` = 50 mm apart. In the reference image a point at planar depth z has disparity d = f·B / z pixels and
appears at column u − d in the right image. We model, on a depth image that is treated as the reference view
(OpenCV axes, x to the right, the second imager at +B along x):

1. **Axial noise** — Intel's RMS model: disparity noise of σ_d = ``subpixel`` px (0.08 for a textured target) in
   the depth imager's pixels, i.e. σ_z = z² · σ_d / (f_d · B) with f_d the depth imager's focal length (384.2 px
   at 640×480): 0.8 mm at 0.5 m, 2.7 mm at 0.8 m, 4.2 mm at 1.0 m. Applied in disparity, so it grows with z².
2. **Occlusion shadows** — a pixel is invalid when the right imager cannot see it: some pixel to its right in
   the same row, nearer to the camera, lands at or left of it in the right image (``u' − d' ≤ u − d`` for
   ``u' > u``). This gives the band of missing depth left of every foreground edge, d_near − d_far wide.
3. **Left-edge band** — pixels whose match would fall outside the right image (u − d < 0) are invalid: the
   band along the left border, f·B / z wide.
4. **Edge dropouts** — pixels next to a depth jump larger than ``edge_jump`` (3×3 neighbourhood) are dropped
   with probability ``edge_dropout``, as the matcher fails on mixed windows.

``strength`` s scales the noise: σ_d and the dropout probability are multiplied by s (the probability clipped
to 1); shadows and the left band are geometric and present whenever s > 0; s = 0 returns the depth unchanged.
Distances in metres; ``fx`` is the focal length (px) of the image being degraded, so disparities are measured in
its pixels (f_d only sets the noise level). Invalid pixels are 0, as in the renderer's output.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

__all__ = ["DepthNoise", "DexNoise", "noise_model", "occlusion_shadow", "upsample_bilinear"]


def occlusion_shadow(depth: np.ndarray, fx: float, baseline: float) -> np.ndarray:
    """Pixels (H, W) bool that the second imager, ``baseline`` m to the right, cannot see (occluded by a nearer
    surface to their right in the same row) or whose match falls left of its image. ``depth`` planar z (m),
    0 = no return (such pixels never occlude)."""
    valid = depth > 0
    with np.errstate(divide="ignore"):
        disparity = np.where(valid, fx * baseline / np.where(valid, depth, 1.0), 0.0)
    cols = np.arange(depth.shape[1], dtype=float)[None, :]
    right = np.where(valid, cols - disparity, np.inf)  # column in the second image
    # smallest right-image column of any pixel strictly to the right: reverse running minimum, shifted by one
    suffix_min = np.minimum.accumulate(right[:, ::-1], axis=1)[:, ::-1]
    beyond = np.concatenate([suffix_min[:, 1:], np.full((depth.shape[0], 1), np.inf)], axis=1)
    occluded = valid & (beyond <= right)
    outside = valid & (right < 0.0)
    return occluded | outside


def _depth_image(depth: np.ndarray) -> np.ndarray:
    """``depth`` as an array, refused unless it is a 2-D float image (what both models degrade)."""
    depth = np.asarray(depth)
    if depth.ndim != 2 or not np.issubdtype(depth.dtype, np.floating):
        raise ValueError(f"depth must be a 2-D float image, got {depth.shape} {depth.dtype}")
    return depth


def _near_jump(depth: np.ndarray, jump: float) -> np.ndarray:
    """Valid pixels with a valid 8-neighbour whose depth differs by more than ``jump`` m."""
    h, w = depth.shape
    padded = np.pad(depth, 1, mode="edge")
    out = np.zeros((h, w), dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy == 0 and dx == 0:
                continue
            n = padded[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            out |= (n > 0) & (np.abs(n - depth) > jump)
    return out & (depth > 0)


@dataclass(frozen=True)
class DepthNoise:
    """The D435-like model of the module docstring; ``strength`` 0 disables it."""

    strength: float = 1.0
    baseline: float = 0.05
    depth_focal: float = 384.2
    subpixel: float = 0.08
    edge_jump: float = 0.02
    edge_dropout: float = 0.5

    def __post_init__(self) -> None:
        if not (np.isfinite(self.strength) and self.strength >= 0.0):
            raise ValueError(f"depth noise strength must be ≥ 0, got {self.strength}")
        if not (self.baseline > 0 and self.depth_focal > 0 and self.subpixel >= 0 and self.edge_jump > 0):
            raise ValueError(f"invalid depth noise parameters {self}")
        if not 0.0 <= self.edge_dropout <= 1.0:
            raise ValueError(f"edge_dropout must be in [0, 1], got {self.edge_dropout}")

    def axial_sigma(self, z: np.ndarray | float) -> np.ndarray:
        """σ_z (m) of the axial noise at planar depth ``z`` (m): s · z² · subpixel / (f_d · B)."""
        return self.strength * np.square(z) * self.subpixel / (self.depth_focal * self.baseline)

    def apply(self, depth: np.ndarray, fx: float, rng: np.random.Generator) -> np.ndarray:
        """A degraded copy of ``depth`` (H, W) float planar metres (0 = no return); ``fx`` px of this image."""
        depth = _depth_image(depth)
        if self.strength == 0.0:
            return depth.copy()
        valid = depth > 0
        invalid = occlusion_shadow(depth, fx, self.baseline)
        p = min(1.0, self.strength * self.edge_dropout)
        jumps = _near_jump(depth, self.edge_jump)
        invalid |= jumps & (rng.random(depth.shape) < p)
        # noise in the depth imager's disparity: d = f_d B / z, d' = d + N(0, (s σ_d)^2), z' = f_d B / d'
        fb = self.depth_focal * self.baseline
        disparity = fb / np.where(valid, depth, 1.0)
        noisy = disparity + self.strength * self.subpixel * rng.standard_normal(depth.shape)
        out = np.where(valid & ~invalid & (noisy > 0), fb / np.maximum(noisy, 1e-9), 0.0)
        return out.astype(depth.dtype)


def upsample_bilinear(grid: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``grid`` (h, w) resampled to ``shape`` (H, W) by bilinear interpolation with pixel-centre alignment: output
    pixel ``i`` samples the input at ``(i + ½)·h/H − ½``, and samples beyond the border blend towards 0 (the
    grid is extended with zeros), as an image resize of order 1 with a constant border does."""
    h, w = grid.shape
    rows = (np.arange(shape[0]) + 0.5) * (h / shape[0]) - 0.5
    cols = (np.arange(shape[1]) + 0.5) * (w / shape[1]) - 0.5
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    return ndimage.map_coordinates(grid, [rr, cc], order=1, mode="grid-constant", cval=0.0)


@dataclass(frozen=True)
class DexNoise:
    """GIGA's "dex" depth noise (after Dex-Net 2.0), which their simulated benchmark applies to each view.

    One multiplicative factor per image, ``α ~ Gamma(k = gamma_shape, θ = gamma_scale)`` (mean k·θ = 1, standard
    deviation √k·θ ≈ 3.2 %), scales the whole depth image; then, with probability ``gp_probability``, a smooth
    additive field is added: i.i.d. ``N(0, gp_sigma²)`` metres on a grid ``gp_downsample`` times coarser than the
    image (120 × 160 at 640 × 480), resampled bilinearly to the image (``upsample_bilinear``), a cheap stand-in
    for a Gaussian process. ``z' = α·z + ε(u, v)`` on pixels with a return; pixels without one (0) stay 0.
    """

    gamma_shape: float = 1000.0
    gamma_scale: float = 0.001
    gp_probability: float = 0.5
    gp_sigma: float = 0.005
    gp_downsample: int = 4

    def __post_init__(self) -> None:
        if not (self.gamma_shape > 0 and self.gamma_scale > 0 and self.gp_sigma >= 0 and self.gp_downsample >= 1):
            raise ValueError(f"invalid dex noise parameters {self}")
        if not 0.0 <= self.gp_probability <= 1.0:
            raise ValueError(f"gp_probability must be in [0, 1], got {self.gp_probability}")

    def apply(self, depth: np.ndarray, fx: float, rng: np.random.Generator) -> np.ndarray:
        """A degraded copy of ``depth`` (H, W) float planar metres (0 = no return); ``fx`` is not used (the model
        is in metres, not in disparity), it keeps the signature of ``DepthNoise.apply``."""
        depth = _depth_image(depth)
        out = depth * rng.gamma(self.gamma_shape, self.gamma_scale)
        if rng.random() < self.gp_probability:
            h, w = depth.shape
            coarse = (max(1, h // self.gp_downsample), max(1, w // self.gp_downsample))
            out = out + upsample_bilinear(rng.normal(0.0, self.gp_sigma, coarse), (h, w))
        return np.where(depth > 0, out, 0.0).astype(depth.dtype)


def noise_model(name: str, strength: float) -> DepthNoise | DexNoise | None:
    """The depth model a task's camera names (``config.NOISE_MODELS``): None when ``strength`` is 0 (exact
    depth), ``DepthNoise(strength)`` for ``d435``, ``DexNoise()`` for ``dex`` (on when ``strength`` > 0)."""
    if strength == 0:
        return None
    if name == "d435":
        return DepthNoise(strength)
    if name == "dex":
        return DexNoise()
    raise ValueError(f"unknown depth noise model {name!r}")
