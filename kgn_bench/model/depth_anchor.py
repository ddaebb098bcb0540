"""What the depth image observes along the ray of an image point: the anchor of the depth-anchored scale.

Frames and units: image pixels ``(u, v)`` follow OpenCV (pixel centres at integers), depths are planar (the
camera-frame z, metres, 0 or non-finite where the sensor has no return), ``K`` is the 3×3 intrinsic matrix.

* ``depth_at``: the median valid depth ``z̃`` in a ``window``×``window`` square around ``rint(u, v)`` (the
  square clamped inside the image).
* ``observed_distance``: the Euclidean distance from the camera centre of that depth on the ray,
  ``d_obs = z̃ · ‖K⁻¹ [u, v, 1]ᵀ‖``: the distance at which the ray through ``(u, v)`` meets the observed surface.

KGN's ``depth`` translation sets ``‖t‖ = d_obs`` at the predicted grasp centre. The depth-anchored scale head
of KGNv2 (``Variant.scale_anchor == "depth"``) predicts instead the residual ``r = ‖t‖ − d_obs`` (metres; how
far the grasp origin lies behind the visible surface along the ray, typically a few centimetres inside the
object) and decodes ``ŝ = d_obs + r̂``. The network regresses a quantity of centimetres instead of the whole
0.5–1.2 m camera distance, and the observed depth at the grasp centre supplies the rest.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEPTH_WINDOW", "depth_at", "observed_distance"]

DEPTH_WINDOW = 5
"""Side (px) of the window around an image point whose median valid depth is taken."""


def depth_at(depth: np.ndarray, uv: np.ndarray, window: int = DEPTH_WINDOW) -> np.ndarray:
    """Median valid (> 0, finite) planar depth (m) in the ``window``×``window`` square around rint(uv) for
    each image point uv (N, 2) px; the square is clamped inside the image; NaN where none is valid."""
    h, w = depth.shape
    half = window // 2
    centre = np.rint(np.asarray(uv, dtype=float)).astype(np.int64).reshape(-1, 2)
    du, dv = np.meshgrid(np.arange(-half, half + 1), np.arange(-half, half + 1))
    u = np.clip(centre[:, :1], 0, w - 1) + du.reshape(1, -1)
    v = np.clip(centre[:, 1:], 0, h - 1) + dv.reshape(1, -1)
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    values = np.where(inside, depth[np.clip(v, 0, h - 1), np.clip(u, 0, w - 1)], np.nan).astype(float)
    values[~(values > 0.0) | ~np.isfinite(values)] = np.nan
    out = np.full(len(centre), np.nan)
    some = ~np.all(np.isnan(values), axis=1)
    out[some] = np.nanmedian(values[some], axis=1)
    return out


def observed_distance(depth: np.ndarray, uv: np.ndarray, K: np.ndarray, window: int = DEPTH_WINDOW) -> np.ndarray:
    """``d_obs = depth_at(depth, uv) · ‖K⁻¹ [u, v, 1]ᵀ‖`` (m) for image points uv (N, 2) px: the distance from
    the camera centre at which the ray through each point meets the observed surface; NaN where the window
    holds no valid depth or the point is not finite."""
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    out = np.full(len(uv), np.nan)
    finite = np.all(np.isfinite(uv), axis=1)
    if not np.any(finite):
        return out
    ray = np.concatenate([uv[finite], np.ones((int(finite.sum()), 1))], axis=1) @ np.linalg.inv(K).T
    out[finite] = depth_at(depth, uv[finite], window) * np.linalg.norm(ray, axis=1)
    return out
