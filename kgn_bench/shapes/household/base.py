"""The common base of the household objects: sizes sampled from ``RANGES``, a visual mesh of parts, and
grasps = the parts' families (``shapes.household.families``) less those whose gripper hits the object's own
other parts. Grasp poses are in the object frame (``T_obj_grasp``)."""

from __future__ import annotations

import abc
from typing import ClassVar

import numpy as np
import trimesh

from kgn_bench.geometry import rot_x
from kgn_bench.grasp import GraspSet
from kgn_bench.shapes.base import GeomSpec, GraspDensity, RestPose, Shape
from kgn_bench.shapes.household.families import SURFACE_SPACING, gripper_sweep_free
from kgn_bench.shapes.primitives import _positive, _uniform

__all__ = ["HouseholdShape", "upright_lying"]


class HouseholdShape(Shape):
    """A household object: sizes named by ``RANGES`` (sampled uniformly), a visual mesh made of part meshes,
    and grasp families built from its parts (``_families``), filtered for collisions with its own parts."""

    RANGES: ClassVar[dict[str, tuple[float, float]]]

    @classmethod
    def sample(cls, rng: np.random.Generator):
        return cls(**{k: _uniform(rng, lo, hi) for k, (lo, hi) in cls.RANGES.items()})

    @classmethod
    def from_dims(cls, dims: dict):
        if not isinstance(dims, dict):
            raise ValueError(f"{cls.name} needs a dict of dimensions, got {dims!r}")
        return cls(**{k: _positive(dims, k) for k in cls.RANGES})

    def dims(self) -> dict:
        return {k: float(getattr(self, k)) for k in self.RANGES}

    def visual_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("mesh", mesh=self.mesh())]

    @abc.abstractmethod
    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        """The part families as (poses (N, 4, 4), widths (N,)) pairs, before the self-collision filter."""

    def surface_points(self) -> np.ndarray:
        """Deterministic sample points (P, 3) on the visual mesh, about ``SURFACE_SPACING`` apart (cached)."""
        cached = self.__dict__.get("_surface_cache")
        if cached is None:
            mesh = self.mesh()
            count = int(np.clip(mesh.area / SURFACE_SPACING**2, 1000, 6000))
            cached = trimesh.sample.sample_surface(mesh, count, seed=0)[0]
            object.__setattr__(self, "_surface_cache", cached)
        return cached

    def grasps(self, density: GraspDensity) -> GraspSet:
        """The part families (``_families``; math in the module doc and on each class) minus the grasps whose
        gripper would hit the object's own other parts (cached per density; do not mutate)."""
        cache = self.__dict__.get("_grasp_cache")
        if cache is None:
            cache = {}
            object.__setattr__(self, "_grasp_cache", cache)
        if density not in cache:
            families = self._families(density)
            poses = np.concatenate([p for p, _ in families])
            widths = np.concatenate([w for _, w in families])
            keep = gripper_sweep_free(self.surface_points(), poses, widths)
            cache[density] = GraspSet.unlabelled(poses[keep], widths[keep])
        return cache[density]


def upright_lying(up: float, down: float, lying: list[tuple[np.ndarray, float]]) -> list[RestPose]:
    poses = [RestPose(np.eye(3), up)] + ([RestPose(rot_x(np.pi), down)] if down > 0 else [])
    return poses + [RestPose(R, p) for R, p in lying]

