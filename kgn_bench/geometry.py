"""Rigid-body geometry: rotations (scipy.spatial.transform), homogeneous poses, pinhole projection.

Conventions (used throughout the package): metres and radians; a pose ``T_a_b`` is a 4×4 homogeneous matrix that maps
points expressed in frame ``b`` into frame ``a`` (``p_a = T_a_b @ p_b``). Rotation matrices act on
column vectors. Pixel coordinates follow OpenCV: pixel ``(u, v)`` has its centre at integer ``(u, v)``,
``u`` grows to the right and ``v`` downwards.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "axis_align",
    "backproject",
    "backproject_strided",
    "frame_from_xz",
    "invert_pose",
    "make_pose",
    "matrix_from_quat_wxyz",
    "matrix_from_rotvec",
    "project",
    "quat_wxyz_from_matrix",
    "quats_wxyz_from_matrices",
    "rot_x",
    "rot_y",
    "rot_z",
    "rotation_angle",
    "rotvec_from_matrix",
    "transform_points",
]


def rot_x(angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about +x."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about +y."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float | np.ndarray) -> np.ndarray:
    """Rotation by ``angle`` (rad) about +z; an array of N angles gives an (N, 3, 3) stack."""
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((*a.shape, 3, 3))
    out[..., 0, 0], out[..., 0, 1] = c, -s
    out[..., 1, 0], out[..., 1, 1] = s, c
    out[..., 2, 2] = 1.0
    return out


def axis_align(spec: tuple[int, int, int]) -> np.ndarray:
    """Signed axis permutation: column k of the result is ``sign(spec[k]) * e_{|spec[k]|}``.

    ``axis_align((-3, 2, 1))`` is the frame whose x axis is −Z, y axis +Y and z axis +X of the parent.
    Raises ``ValueError`` if the result is not a proper rotation.
    """
    R = np.zeros((3, 3))
    for col, s in enumerate(spec):
        if abs(s) not in (1, 2, 3):
            raise ValueError(f"axis_align entries must be ±1, ±2 or ±3, got {spec}")
        R[abs(s) - 1, col] = np.sign(s)
    if not np.isclose(np.linalg.det(R), 1.0):
        raise ValueError(f"axis_align{spec} is not a right-handed rotation")
    return R


def frame_from_xz(x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The rotation(s) (..., 3, 3) whose columns are ``x``, ``y = z × x`` and ``z``, for unit ``x ⟂ z``:
    the grasp frame from its approach (x) and closing (z) axes, or any frame from two of its axes."""
    return np.stack([x, np.cross(z, x), z], axis=-1)


def make_pose(R: np.ndarray | None = None, t: np.ndarray | None = None) -> np.ndarray:
    """4×4 pose from a rotation (default identity) and a translation (default zero)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if t is not None:
        T[:3, 3] = t
    return T


def invert_pose(T: np.ndarray) -> np.ndarray:
    """Inverse of one pose (4, 4) or a stack (..., 4, 4): ``[Rᵀ, −Rᵀt]``."""
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    Rt = np.swapaxes(R, -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, t)
    out[..., 3, 3] = 1.0
    return out


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply pose ``T`` (4, 4) to points (..., 3): ``R p + t``."""
    return points @ T[:3, :3].T + T[:3, 3]


def rotation_angle(Ra: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Geodesic angle (rad) between rotations: ``arccos((tr(Raᵀ Rb) − 1) / 2)``, broadcast over stacks."""
    tr = np.einsum("...ij,...ij->...", Ra, Rb)
    return np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))


def project(points_cam: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Pinhole projection of camera-frame points (..., 3) (OpenCV frame, z forward) to pixels (..., 2).

    ``u = fx·x/z + cx``, ``v = fy·y/z + cy``. Points with z ≤ 0 give non-finite or mirrored pixels;
    callers that care must test ``z > 0`` themselves.
    """
    z = points_cam[..., 2:3]
    uv1 = points_cam @ K.T
    return uv1[..., :2] / z


def backproject(depth: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Back-project a planar depth image (H, W) in metres to camera-frame points (H, W, 3).

    ``x = (u − cx)·z/fx``, ``y = (v − cy)·z/fy``; pixels with depth 0 (no return) map to the origin.
    """
    h, w = depth.shape
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    z = depth.astype(np.float64)
    x = (u - K[0, 2]) * z / K[0, 0]
    y = (v - K[1, 2]) * z / K[1, 1]
    return np.stack([x, y, z], axis=-1)


def backproject_strided(depth: np.ndarray, K: np.ndarray, stride: int) -> np.ndarray:
    """Back-project every ``stride``-th pixel of ``depth`` (rows and columns), (H', W', 3) camera-frame
    points. Pixel ``(u', v')`` of the subsampled image is pixel ``(s·u', s·v')`` of the full one, so its
    intrinsics are ``diag(1/s, 1/s, 1) · K``."""
    Ks = np.diag([1.0 / stride, 1.0 / stride, 1.0]) @ K
    return backproject(depth[::stride, ::stride], Ks)


def quat_wxyz_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z), w ≥ 0 (MuJoCo's order), of a rotation matrix (scipy)."""
    q = Rotation.from_matrix(np.asarray(R, dtype=float)).as_quat(canonical=True, scalar_first=True)
    return q / np.linalg.norm(q)


def quats_wxyz_from_matrices(R: np.ndarray) -> np.ndarray:
    """(N, 4): ``quat_wxyz_from_matrix`` of each of the (N, 3, 3) rotation matrices ``R``, bit for bit, in
    one scipy call (a per-matrix call costs about 0.15 ms, most of it scipy's overhead)."""
    q = Rotation.from_matrix(np.asarray(R, dtype=float).reshape(-1, 3, 3)).as_quat(canonical=True, scalar_first=True)
    return np.stack([row / np.linalg.norm(row) for row in q]) if len(q) else q


def matrix_from_quat_wxyz(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z); the quaternion is normalised first (scipy)."""
    return Rotation.from_quat(np.asarray(q, dtype=float), scalar_first=True).as_matrix()


def matrix_from_rotvec(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (axis · angle, rad): ``exp([w]×)`` (scipy)."""
    return Rotation.from_rotvec(np.asarray(w, dtype=float)).as_matrix()


def rotvec_from_matrix(R: np.ndarray) -> np.ndarray:
    """Rotation vector (axis · angle, angle in [0, π]) of the rotation matrix ``R``: ``log(R)`` (scipy)."""
    return Rotation.from_matrix(np.asarray(R, dtype=float)).as_rotvec()
