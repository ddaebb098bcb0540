"""Gripper dimensions: the one source for the collision proxy (and, later, the MJCF and the selector).

All lengths in metres, expressed in the grasp frame (DESIGN §4): origin at the fingertip midpoint,
+x = approach (the gripper body lies at x < 0), z = closing axis with the left finger at +z.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["GRIPPER", "GripperGeometry"]


@dataclass(frozen=True)
class GripperGeometry:
    """Dimensions of the parallel-jaw gripper and of its collision proxy.

    The proxy used to label ground-truth grasps (reference facts §2.5) is a solid box occupying
    ``x ∈ [−proxy_depth, 0]``, ``|y| ≤ proxy_thickness / 2`` and ``|z| ≤ w/2 + proxy_clearance`` in the
    grasp frame, for a grasp of width ``w``: it covers the fingers, the palm and the space between them.
    """

    proxy_depth: float = 0.10
    proxy_thickness: float = 0.02
    proxy_clearance: float = 0.02

    def proxy_half_extents(self, width: float | np.ndarray) -> np.ndarray:
        """Half extents (..., 3) of the proxy box along the grasp frame's x, y, z axes."""
        w = np.asarray(width, dtype=float)
        hx = np.full_like(w, self.proxy_depth / 2.0)
        hy = np.full_like(w, self.proxy_thickness / 2.0)
        hz = w / 2.0 + self.proxy_clearance
        return np.stack([hx, hy, hz], axis=-1)

    @property
    def proxy_centre(self) -> np.ndarray:
        """Centre of the proxy box in the grasp frame: ``(−proxy_depth/2, 0, 0)``."""
        return np.array([-self.proxy_depth / 2.0, 0.0, 0.0])

    def proxy_corners(self, poses: np.ndarray, widths: np.ndarray) -> np.ndarray:
        """The 8 corners (N, 8, 3) of the proxy boxes of grasps ``poses`` (N, 4, 4), in the poses' frame."""
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        local = self.proxy_centre + signs[None] * self.proxy_half_extents(widths)[:, None, :]
        return np.einsum("nij,nkj->nki", poses[:, :3, :3], local) + poses[:, None, :3, 3]


GRIPPER = GripperGeometry()
