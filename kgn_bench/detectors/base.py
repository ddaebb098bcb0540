"""The detector protocol: what a grasp detector sees and what it returns.

An ``Observation`` holds only what a real RGB-D camera gives: RGB, planar depth, intrinsics and the
camera pose (OpenCV camera-to-world). ``Candidates`` are grasp poses in the *camera* frame (grasp frame of
DESIGN §4), with widths, confidences, reprojection errors (NaN where a detector has none) and, optionally,
the image keypoints they came from.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from kgn_bench.errors import KGNBenchError
from kgn_bench.geometry import backproject, transform_points
from kgn_bench.sim.camera import Intrinsics

__all__ = ["Candidates", "Detector", "DetectorError", "Observation"]


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
        depth = self.depth[::stride, ::stride]
        K = np.diag([1.0 / stride, 1.0 / stride, 1.0]) @ self.intrinsics.K  # pixel u' of the strided image = u / s
        return transform_points(self.camera_pose, backproject(depth, K)[depth > 0])


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


@runtime_checkable
class Detector(Protocol):
    """A grasp detector. ``privileged`` detectors (the oracle) also get the simulator via ``attach``."""

    name: str
    privileged: bool

    def reset(self, seed: list[int]) -> None:
        """Start a trial: seed any randomness from ``seed`` (the run's seed and the trial index)."""

    def detect(self, observation: Observation) -> Candidates:
        """Grasp candidates for one observation (may be empty)."""
