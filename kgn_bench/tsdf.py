"""A truncated signed distance field (TSDF) of a cubic workspace, fused from planar depth images.

The volume is a ``resolution³`` grid of voxels of side ``voxel = size / resolution`` over the cube
``[0, size]³`` of the *grid frame*, whose axes are the world's and whose origin is the cube's corner:
``T_world_grid`` is a pure translation. Voxel ``(i, j, k)`` is centred at ``((i, j, k) + ½) · voxel`` in the
grid frame.

Fusion (one view): a voxel centre ``p`` seen at ``p_c = T_cam_grid · p`` (OpenCV camera frame, ``z > 0``)
projects to the pixel ``(u, v) = (⌊f_x x/z + c_x + ½⌋, ⌊f_y y/z + c_y + ½⌋)``. With the observed planar depth
``d`` there, its signed distance along the ray is

    sdf = (d − z) · √(1 + (x/z)² + (y/z)²)

(positive in front of the surface, in the free space the camera sees through). A voxel with
``sdf ≥ −τ`` (``τ`` the truncation, ``truncation_voxels · voxel``) takes ``t = min(1, sdf/τ)`` into a
running mean weighted by the number of views; voxels further behind the surface, outside the image or
with no depth keep what they had. This is the uniform TSDF volume of Curless and Levoy as Open3D
integrates it, which VGN and GIGA feed to their networks.

``network_input`` is that network's input: ``(t + 1)/2`` where a voxel was observed and ``|t| < 0.98``,
and 0 elsewhere (unobserved space and free space far from any surface alike), in ``[i, j, k]`` order.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kgn_bench.camera import Intrinsics
from kgn_bench.geometry import invert_pose, transform_points

__all__ = ["SURFACE_BAND", "TSDFVolume", "VoxelGrid"]

SURFACE_BAND = 0.98
"""A voxel enters the network input when its normalised distance lies in ``[−0.98, 0.98)``."""


@dataclass(frozen=True)
class VoxelGrid:
    """A cube of ``resolution³`` voxels of side ``size`` metres (VGN's: 30 cm, 40³, truncation 4 voxels)."""

    size: float = 0.30
    resolution: int = 40
    truncation_voxels: float = 4.0

    def __post_init__(self) -> None:
        if not (self.size > 0 and self.resolution > 0 and self.truncation_voxels > 0):
            raise ValueError(f"invalid voxel grid {self}")

    @property
    def voxel(self) -> float:
        """Side of one voxel, in metres."""
        return self.size / self.resolution

    @property
    def truncation(self) -> float:
        """τ, the distance at which the signed distance saturates, in metres."""
        return self.truncation_voxels * self.voxel

    def centres(self) -> np.ndarray:
        """(R, R, R, 3) voxel centres ``(idx + ½) · voxel`` in the grid frame, indexed ``[i, j, k]``."""
        idx = (np.arange(self.resolution) + 0.5) * self.voxel
        return np.stack(np.meshgrid(idx, idx, idx, indexing="ij"), axis=-1)


@dataclass
class TSDFVolume:
    """A TSDF over ``grid`` placed at ``T_world_grid`` (a translation: the cube's corner in the world)."""

    grid: VoxelGrid = field(default_factory=VoxelGrid)
    T_world_grid: np.ndarray = field(default_factory=lambda: np.eye(4))
    tsdf: np.ndarray = field(init=False)
    weight: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        shape = (self.grid.resolution,) * 3
        self.tsdf = np.ones(shape, dtype=np.float32)
        self.weight = np.zeros(shape, dtype=np.float32)
        self._centres = self.grid.centres().reshape(-1, 3)

    def integrate(self, depth: np.ndarray, intrinsics: Intrinsics, T_world_cam: np.ndarray) -> None:
        """Fuse one planar depth image (metres; 0 or non-finite = no reading) seen from ``T_world_cam``."""
        if depth.shape != (intrinsics.height, intrinsics.width):
            raise ValueError(f"depth of shape {depth.shape} for a {intrinsics.width}×{intrinsics.height} camera")
        T_cam_grid = invert_pose(T_world_cam) @ self.T_world_grid
        p = transform_points(T_cam_grid, self._centres)
        z = p[:, 2]
        in_front = z > 1e-9
        zs = np.where(in_front, z, 1.0)
        a, b = p[:, 0] / zs, p[:, 1] / zs
        u = np.floor(a * intrinsics.fx + intrinsics.cx + 0.5).astype(np.int64)
        v = np.floor(b * intrinsics.fy + intrinsics.cy + 0.5).astype(np.int64)
        seen = in_front & (u >= 0) & (u < intrinsics.width) & (v >= 0) & (v < intrinsics.height)
        d = np.zeros_like(z)
        d[seen] = depth[v[seen], u[seen]]
        seen &= np.isfinite(d) & (d > 0)
        sdf = (d - z) * np.sqrt(1.0 + a * a + b * b)
        update = seen & (sdf >= -self.grid.truncation)
        t = np.minimum(1.0, sdf[update] / self.grid.truncation)
        tsdf, weight = self.tsdf.reshape(-1), self.weight.reshape(-1)
        w = weight[update]
        tsdf[update] = (tsdf[update] * w + t) / (w + 1.0)
        weight[update] = w + 1.0

    def network_input(self) -> np.ndarray:
        """(R, R, R) float32: ``(t + 1)/2`` on observed voxels with ``−0.98 ≤ t < 0.98``, else 0."""
        keep = (self.weight > 0) & (self.tsdf >= -SURFACE_BAND) & (self.tsdf < SURFACE_BAND)
        return np.where(keep, (self.tsdf + 1.0) / 2.0, 0.0).astype(np.float32)
