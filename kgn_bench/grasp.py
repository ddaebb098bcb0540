"""The grasp frame, keypoint boxes, the 180° symmetry and arrays of grasps.

Grasp frame: origin at the midpoint between the fingertips; +x = approach direction (the
fingers point along +x, the gripper body lies at x < 0); z = closing axis with the left finger at +z;
y = z × x. A grasp and the same grasp turned 180° about its x axis are the same physical grasp.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kgn_bench.geometry import rotation_angle

__all__ = [
    "FLIP_X180",
    "KEYPOINT_LINKS",
    "KEYPOINT_NAMES",
    "GraspSet",
    "flip_180",
    "grasp_rotation_error",
    "keypoint_box",
    "keypoints_in_frame",
]

FLIP_X180 = np.diag([1.0, -1.0, -1.0, 1.0])
"""Right-multiplying a grasp pose by this turns it 180° about its approach axis (swaps the fingers)."""

KEYPOINT_NAMES = ("L", "R", "TL", "TR")
KEYPOINT_LINKS = ((0, 2), (1, 3), (2, 3))
"""Index pairs drawn for a box: L–TL, R–TR, TL–TR."""


def keypoint_box(side: float) -> np.ndarray:
    """The 4 box keypoints (L, R, TL, TR) of side ``a`` in the grasp frame, shape (4, 3).

    ``L = (0, 0, a/2)``, ``R = (0, 0, −a/2)``, ``TL = (−a, 0, a/2)``, ``TR = (−a, 0, −a/2)``.
    """
    if not side > 0.0:
        raise ValueError(f"keypoint box side must be positive, got {side}")
    h = side / 2.0
    return np.array([[0.0, 0.0, h], [0.0, 0.0, -h], [-side, 0.0, h], [-side, 0.0, -h]])


def keypoints_in_frame(poses: np.ndarray, sides: float | np.ndarray) -> np.ndarray:
    """Box keypoints of grasps ``poses`` (N, 4, 4) with sides (scalar or (N,)), in the poses' frame: (N, 4, 3)."""
    a = np.broadcast_to(np.asarray(sides, dtype=float), (poses.shape[0],))
    if np.any(~(a > 0.0)):
        raise ValueError("keypoint box sides must be positive")
    unit = keypoint_box(1.0)
    local = unit[None] * a[:, None, None]
    return np.einsum("nij,nkj->nki", poses[:, :3, :3], local) + poses[:, None, :3, 3]


def flip_180(poses: np.ndarray) -> np.ndarray:
    """The same grasps turned 180° about their approach axis: ``T · diag(1, −1, −1, 1)``."""
    return poses @ FLIP_X180


def grasp_rotation_error(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Rotation error (rad) between grasp orientations that respects the 180° symmetry:
    ``min(d(Ra, Rb), d(Ra, Rb · diag(1, −1, −1)))`` with d the geodesic angle; broadcast over stacks."""
    return np.minimum(rotation_angle(Ra, Rb), rotation_angle(Ra, Rb @ FLIP_X180[:3, :3]))


@dataclass(frozen=True)
class GraspSet:
    """N grasps in one frame: ``poses`` (N, 4, 4) map grasp-frame points into that frame.

    ``widths`` (N,) are jaw openings in metres before closing; ``collides`` (N,) flags grasps whose
    gripper proxy hits the table or another object (False where unlabelled).
    """

    poses: np.ndarray
    widths: np.ndarray
    collides: np.ndarray

    def __post_init__(self) -> None:
        n = self.poses.shape[0]
        if self.poses.shape != (n, 4, 4) or self.widths.shape != (n,) or self.collides.shape != (n,):
            raise ValueError(
                f"inconsistent grasp arrays: poses {self.poses.shape}, widths {self.widths.shape}, "
                f"collides {self.collides.shape}"
            )

    @classmethod
    def empty(cls) -> GraspSet:
        return cls(np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0, dtype=bool))

    @classmethod
    def unlabelled(cls, poses: np.ndarray, widths: np.ndarray) -> GraspSet:
        return cls(poses, np.asarray(widths, dtype=float), np.zeros(len(poses), dtype=bool))

    def __len__(self) -> int:
        return int(self.poses.shape[0])

    def transformed(self, T: np.ndarray) -> GraspSet:
        """The same grasps expressed in another frame: ``T @ poses`` where ``T`` maps this frame into it."""
        return GraspSet(T @ self.poses, self.widths, self.collides)

    def with_collisions(self, collides: np.ndarray) -> GraspSet:
        return GraspSet(self.poses, self.widths, np.asarray(collides, dtype=bool))

    def free(self) -> GraspSet:
        """The collision-free subset."""
        return self.subset(~self.collides)

    def subset(self, keep: np.ndarray) -> GraspSet:
        """The grasps that ``keep`` (a boolean mask or indices) selects, in that order."""
        return GraspSet(self.poses[keep], self.widths[keep], self.collides[keep])

    @staticmethod
    def concatenate(sets: list[GraspSet]) -> GraspSet:
        if not sets:
            return GraspSet.empty()
        return GraspSet(
            np.concatenate([s.poses for s in sets]),
            np.concatenate([s.widths for s in sets]),
            np.concatenate([s.collides for s in sets]),
        )
