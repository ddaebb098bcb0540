"""Pinhole intrinsics, camera poses, and the conversion between MuJoCo's and OpenCV's camera frames.

Camera poses are camera-to-world 4×4 matrices in the OpenCV convention (x right, y down, z forward)
everywhere in the project. MuJoCo cameras look along their local −z with y up; ``convert_camera_frame``
is the single place where one becomes the other.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from kgn_bench.geometry import make_pose

__all__ = [
    "GIGA",
    "INTRINSICS",
    "REALSENSE",
    "CameraSampler",
    "Intrinsics",
    "clip_far",
    "convert_camera_frame",
    "crop_depth",
    "look_at",
    "orbit_pose",
]

_MJ_CV = np.diag([1.0, -1.0, -1.0, 1.0])


def convert_camera_frame(pose_c2w: np.ndarray) -> np.ndarray:
    """Convert a camera-to-world pose between the MuJoCo/OpenGL and the OpenCV camera frame.

    MuJoCo: x right, y up, looking along −z. OpenCV: x right, y down, looking along +z. The two frames
    differ by a 180° turn about x, so ``T_world_cv = T_world_mj · diag(1, −1, −1, 1)``; the map is its own
    inverse and converts either way.
    """
    return pose_c2w @ _MJ_CV


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels (OpenCV convention: pixel centres at integer coordinates)."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self) -> None:
        if not (self.fx > 0 and self.fy > 0 and self.width > 0 and self.height > 0):
            raise ValueError(f"invalid intrinsics {self}")

    @property
    def K(self) -> np.ndarray:
        """3×3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> Intrinsics:
        return cls(
            fx=float(d["fx"]),
            fy=float(d["fy"]),
            cx=float(d["cx"]),
            cy=float(d["cy"]),
            width=int(d["width"]),
            height=int(d["height"]),
        )


REALSENSE = Intrinsics(
    fx=616.36529541, fy=616.20294189, cx=310.25881958, cy=236.59980774, width=640, height=480
)
"""RealSense colour intrinsics at 640×480 used by the reference implementation's PS dataset."""

GIGA = Intrinsics(fx=540.0, fy=540.0, cx=320.0, cy=240.0, width=640, height=480)
"""The simulated camera of VGN's and GIGA's benchmark: 640×480, f = 540 px, the principal point at the centre."""

INTRINSICS: dict[str, Intrinsics] = {"realsense": REALSENSE, "giga": GIGA}
"""The cameras a task file can name (``[camera] intrinsics``)."""


_UP = np.array([0.0, 0.0, 1.0])


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray = _UP) -> np.ndarray:
    """OpenCV camera-to-world pose at ``eye`` whose optical axis (+z) points at ``target`` with zero roll.

    Zero roll: the camera x axis is horizontal (perpendicular to ``up``) and the image "down" (+y) points
    away from ``up``. When the view direction is parallel to ``up`` (looking straight down), the x axis is
    taken as world +x.
    """
    eye = np.asarray(eye, dtype=float)
    z = np.asarray(target, dtype=float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        x = np.array([1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return make_pose(np.stack([x, y, z], axis=1), eye)


def orbit_pose(distance: float, elevation: float, azimuth: float) -> np.ndarray:
    """Camera on a sphere around the world origin, looking at it with zero roll.

    Position ``R_z(azimuth) · (0, d·cos(elevation), d·sin(elevation))`` (as the reference implementation);
    ``elevation = π/2`` is straight down. At exactly π/2 the image x axis is taken as
    ``R_z(azimuth)·(−1, 0, 0)``, the limit of the zero-roll frame as the elevation approaches 90°.
    """
    ca, sa = np.cos(azimuth), np.sin(azimuth)
    eye = distance * np.array([-sa * np.cos(elevation), ca * np.cos(elevation), np.sin(elevation)])
    # x axis horizontal: perpendicular to the vertical plane through the eye and the origin.
    x = np.array([-ca, -sa, 0.0])
    z = -eye / np.linalg.norm(eye)
    y = np.cross(z, x)
    return make_pose(np.stack([x, y, z], axis=1), eye)


@dataclass(frozen=True)
class CameraSampler:
    """Random viewpoints looking at the table centre, zero roll (the PS dataset's camera sampling).

    distance ~ U[distance_range], elevation ~ U[elevation_range] (rad), azimuth ~ U[0, 2π).
    """

    distance_range: tuple[float, float] = (0.6, 1.0)
    elevation_range: tuple[float, float] = (np.deg2rad(30.0), np.deg2rad(90.0))

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` camera-to-world poses (n, 4, 4), OpenCV convention."""
        poses = []
        for _ in range(n):
            d = rng.uniform(*self.distance_range)
            el = rng.uniform(*self.elevation_range)
            az = rng.uniform(0.0, 2.0 * np.pi)
            poses.append(orbit_pose(d, el, az))
        return np.stack(poses)


def clip_far(depth: np.ndarray, far: float) -> np.ndarray:
    """The planar depth image (metres, 0 = nothing seen) of a camera whose far clipping plane lies at ``far``:
    every pixel deeper than ``far`` or seeing nothing reads ``far``, as PyBullet's camera returns its far plane
    for the background (GIGA's: 2 m). ``far`` 0 leaves ``depth`` as it is."""
    if far <= 0:
        return depth
    return np.where((depth > far) | (depth <= 0), far, depth).astype(depth.dtype)


def crop_depth(depth: np.ndarray, K: np.ndarray, T_world_cam: np.ndarray, lo: np.ndarray, hi: np.ndarray
               ) -> np.ndarray:
    """``depth`` (planar, metres, 0 = nothing seen) with every pixel whose back-projected point, in the world
    frame through ``T_world_cam``, lies outside the box ``lo ≤ p ≤ hi`` (world, m) set to 0: what a pipeline
    that crops its input to a workspace sees (GIGA crops every method's input to its 30 cm cube)."""
    from kgn_bench.geometry import backproject, transform_points

    points = transform_points(T_world_cam, backproject(depth, K).reshape(-1, 3)).reshape(*depth.shape, 3)
    inside = np.all((points >= lo) & (points <= hi), axis=-1)
    return np.where(inside & (depth > 0), depth, 0.0).astype(depth.dtype)
