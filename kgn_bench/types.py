"""The data that detectors, the model, the simulator and the harness exchange, in one module that
imports neither MuJoCo nor torch.

``Observation`` holds only what a real RGB-D camera gives: RGB, planar depth, intrinsics and the camera
pose ``T_world_cam`` (OpenCV axes: x right, y down, z forward). ``Candidates`` are grasp poses in the
*camera* frame, ``T_cam_grasp``, in the project's grasp frame (origin at the fingertip midpoint, +x the
approach, z the closing axis; see ``kgn_bench.grasp``), with widths (m), confidences, reprojection errors
(px, NaN where a detector has none) and, optionally, the image keypoints they came from. ``RGBD`` is one
rendered or stored view with its instance mask.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kgn_bench.camera import Intrinsics
from kgn_bench.errors import KGNBenchError
from kgn_bench.geometry import backproject_strided, transform_points

__all__ = ["RGBD", "Candidates", "DetectorError", "Observation"]


@dataclass
class RGBD:
    """One view: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 metres (0 = no return), ``mask`` (H, W)
    uint8 instance labels (0 = table or background, i + 1 = object i)."""

    rgb: np.ndarray
    depth: np.ndarray
    mask: np.ndarray


class DetectorError(KGNBenchError, ValueError):
    """An observation a detector cannot work with (wrong shape, dtype or no valid depth)."""


@dataclass(frozen=True)
class Observation:
    """One RGB-D capture: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) float32 metres (planar z, 0 = no return),
    ``intrinsics``, ``camera_pose`` = ``T_world_cam`` (OpenCV axes)."""

    rgb: np.ndarray
    depth: np.ndarray
    intrinsics: Intrinsics
    camera_pose: np.ndarray

    def validate(self) -> None:
        """Raise ``DetectorError`` naming the problem if the observation is malformed."""
        h, w = self.intrinsics.height, self.intrinsics.width
        if self.rgb.shape != (h, w, 3) or self.rgb.dtype != np.uint8:
            raise DetectorError(f"rgb must be ({h}, {w}, 3) uint8, got {self.rgb.shape} {self.rgb.dtype}")
        if self.depth.shape != (h, w) or not np.issubdtype(self.depth.dtype, np.floating):
            raise DetectorError(f"depth must be ({h}, {w}) float metres, got {self.depth.shape} {self.depth.dtype}")
        if self.camera_pose.shape != (4, 4) or not np.all(np.isfinite(self.camera_pose)):
            raise DetectorError("camera_pose must be a finite 4×4 camera-to-world matrix")
        if np.any(np.isnan(self.depth)):
            raise DetectorError("depth contains NaN (use 0 for no measurement)")
        if not np.any(self.depth > 0):
            raise DetectorError("depth is empty (no valid measurement)")

    def points_world(self, stride: int = 1) -> np.ndarray:
        """Valid depth pixels back-projected to the world frame, (N, 3), every ``stride``-th pixel."""
        points = backproject_strided(self.depth, self.intrinsics.K, stride)
        return transform_points(self.camera_pose, points[self.depth[::stride, ::stride] > 0])


@dataclass(frozen=True)
class Candidates:
    """Grasp candidates in the camera frame: ``poses`` (N, 4, 4) ``T_cam_grasp``, ``widths`` (N,) m,
    ``confidences`` (N,), ``reprojection_errors`` (N,) px (NaN = none), ``keypoints`` (N, 4, 2) px or None."""

    poses: np.ndarray
    widths: np.ndarray
    confidences: np.ndarray
    reprojection_errors: np.ndarray
    keypoints: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.poses)
        if self.poses.shape != (n, 4, 4):
            raise DetectorError(f"candidate poses must be (N, 4, 4), got {self.poses.shape}")
        for name in ("widths", "confidences", "reprojection_errors"):
            if getattr(self, name).shape != (n,):
                raise DetectorError(f"candidate {name} must be ({n},), got {getattr(self, name).shape}")
        if self.keypoints is not None and self.keypoints.shape != (n, 4, 2):
            raise DetectorError(f"candidate keypoints must be ({n}, 4, 2), got {self.keypoints.shape}")

    def __len__(self) -> int:
        return len(self.poses)

    @classmethod
    def empty(cls) -> Candidates:
        return cls(np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0), np.zeros(0))

    def world_poses(self, camera_pose: np.ndarray) -> np.ndarray:
        """``T_world_grasp = T_world_cam · T_cam_grasp`` for every candidate, (N, 4, 4)."""
        return camera_pose @ self.poses
