"""What every object shape provides: sizes, meshes, MuJoCo geoms, rest poses and grasp families.

Object frame: each shape defines its own (documented on the class); an object's world pose maps
object-frame points to the world. Grasp families are returned in the object frame; the world grasps are
``T_world_obj @ G``.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import trimesh

from kgn_bench.geometry import matrix_from_quat_wxyz
from kgn_bench.grasp import GraspSet

__all__ = ["EVAL_DENSITY", "TRAIN_DENSITY", "GeomSpec", "GraspDensity", "RestPose", "Shape"]


@dataclass(frozen=True)
class GraspDensity:
    """How densely grasp families are sampled: ``translations`` positions along a family's free
    translation and ``angles`` unique angles over [0, 2π) (no duplicate endpoint at 2π, for training and
    evaluation alike)."""

    translations: int
    angles: int

    def __post_init__(self) -> None:
        if self.translations < 1 or self.angles < 1:
            raise ValueError(f"grasp density needs ≥ 1 translation and angle, got {self}")

    def angle_samples(self) -> np.ndarray:
        return 2.0 * np.pi * np.arange(self.angles) / self.angles


TRAIN_DENSITY = GraspDensity(translations=5, angles=11)
EVAL_DENSITY = GraspDensity(translations=10, angles=30)


@dataclass(frozen=True)
class GeomSpec:
    """One MuJoCo geom of an object, in the object frame.

    ``kind`` is a MuJoCo geom type (box, cylinder, sphere, capsule or mesh); ``size`` follows MuJoCo's
    half-size conventions; ``pos``/``quat`` (w, x, y, z) place it in the object frame; ``mesh`` holds
    the vertices and faces of a mesh geom.
    """

    kind: str
    size: tuple[float, ...] = ()
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    quat: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    mesh: trimesh.Trimesh | None = field(default=None, compare=False)

    def volume(self) -> float:
        """Volume in m³ of a primitive (boxes, cylinders, spheres); meshes use trimesh."""
        s = self.size
        if self.kind == "box":
            return 8.0 * s[0] * s[1] * s[2]
        if self.kind == "cylinder":
            return np.pi * s[0] ** 2 * 2.0 * s[1]
        if self.kind == "sphere":
            return 4.0 / 3.0 * np.pi * s[0] ** 3
        if self.kind == "mesh" and self.mesh is not None:
            return float(abs(self.mesh.volume))
        raise ValueError(f"no volume for geom kind {self.kind!r}")

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(P,) bool: which object-frame ``points`` (P, 3) lie inside this geom (boundary included). A mesh geom
        counts as its convex hull, as MuJoCo collides it; a capsule is a cylinder of half-length ``size[1]``
        along z with hemispherical caps of radius ``size[0]``."""
        R = matrix_from_quat_wxyz(np.asarray(self.quat, dtype=float))
        local = (np.asarray(points, dtype=float) - np.asarray(self.pos)) @ R
        s = self.size
        if self.kind == "box":
            return np.all(np.abs(local) <= np.asarray(s), axis=1)
        if self.kind == "cylinder":
            return (np.hypot(local[:, 0], local[:, 1]) <= s[0]) & (np.abs(local[:, 2]) <= s[1])
        if self.kind == "sphere":
            return np.linalg.norm(local, axis=1) <= s[0]
        if self.kind == "capsule":
            axial = np.clip(local[:, 2], -s[1], s[1])
            return np.linalg.norm(local - np.c_[np.zeros((len(local), 2)), axial], axis=1) <= s[0]
        if self.kind == "mesh" and self.mesh is not None:
            hull = self.mesh.convex_hull
            offsets = np.einsum("fj,fj->f", hull.face_normals, hull.triangles[:, 0])
            return np.all(local @ hull.face_normals.T <= offsets + 1e-9, axis=1)
        raise ValueError(f"cannot test containment for geom kind {self.kind!r}")


@dataclass(frozen=True)
class RestPose:
    """A candidate resting orientation: ``R`` maps object-frame vectors to world, ``probability`` its
    quasi-static likelihood. Gravity then settles the object in MuJoCo."""

    R: np.ndarray
    probability: float


class Shape(abc.ABC):
    """A parametric object. Subclasses are frozen dataclasses holding the sizes (metres)."""

    name: ClassVar[str]
    axisymmetric: ClassVar[bool] = False
    """True when the object is symmetric about its z axis (its frame's x axis may be chosen freely)."""
    grasps_verified: ClassVar[bool] = False
    """True when ``grasps`` returns grasps each checked in physics (an imported mesh), with approaches all
    round each closing axis; False for closed-form families."""

    density: ClassVar[float] = 500.0
    """Material density (kg/m³) used for the mass before clipping to ``MASS_RANGE``."""

    MASS_RANGE: ClassVar[tuple[float, float]] = (0.03, 0.4)

    @classmethod
    @abc.abstractmethod
    def sample(cls, rng: np.random.Generator) -> Shape:
        """Draw sizes from the reference ranges."""

    @classmethod
    @abc.abstractmethod
    def from_dims(cls, dims: dict) -> Shape:
        """Rebuild from ``dims()`` (as stored in annotations); raises ``ValueError`` on bad values."""

    @abc.abstractmethod
    def dims(self) -> dict:
        """Named sizes in metres, JSON-serialisable."""

    @abc.abstractmethod
    def _build_mesh(self) -> trimesh.Trimesh:
        """Build the visual mesh (called once per instance by ``mesh``)."""

    def mesh(self) -> trimesh.Trimesh:
        """Smooth, watertight visual mesh in the object frame (built once, then cached; do not mutate)."""
        cached = self.__dict__.get("_mesh_cache")
        if cached is None:
            cached = self._build_mesh()
            object.__setattr__(self, "_mesh_cache", cached)
        return cached

    @abc.abstractmethod
    def collision_geoms(self) -> list[GeomSpec]:
        """Collision geometry in the object frame; hollow where the shape is hollow."""

    def visual_geoms(self) -> list[GeomSpec]:
        """Geoms that are rendered; by default the collision geoms themselves."""
        return self.collision_geoms()

    @abc.abstractmethod
    def rest_poses(self) -> list[RestPose]:
        """Resting orientations to drop the object from, with probabilities summing to 1."""

    @abc.abstractmethod
    def grasps(self, density: GraspDensity) -> GraspSet:
        """Closed-form ground-truth grasp families in the object frame (unlabelled)."""

    @abc.abstractmethod
    def volume(self) -> float:
        """Volume of material in m³."""

    def mass(self) -> float:
        """Physical mass in kg: density × volume, clipped to ``MASS_RANGE``."""
        lo, hi = self.MASS_RANGE
        return float(np.clip(self.density * self.volume(), lo, hi))

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(P,) bool: which object-frame ``points`` (P, 3) lie inside any collision geom."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        inside = np.zeros(len(points), dtype=bool)
        for g in self.collision_geoms():
            inside |= g.contains(points)
        return inside

    def lowest_point(self, R: np.ndarray) -> float:
        """Lowest world z of the object's mesh when its frame is rotated by ``R`` and sits at the origin."""
        return float((self.mesh().vertices @ R.T)[:, 2].min())
