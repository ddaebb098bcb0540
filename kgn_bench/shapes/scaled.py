"""A shape scaled uniformly about its object frame's origin, and GIGA's object sizes.

``ScaledShape(inner, s)`` is the object ``inner`` grown (s > 1) or shrunk (s < 1) by the factor ``s`` about the
origin of ``inner``'s object frame: an object-frame point ``p`` of ``inner`` is the point ``s p`` of the scaled
shape. Its object frame is ``inner``'s (same origin, same axes), so a world pose ``T_world_obj`` means the same
for both; only lengths change:

* meshes: every vertex ``v → s v`` (a new mesh: ``inner``'s cached meshes are never touched);
* geoms (``GeomSpec``): ``size → s size`` (MuJoCo's box half sizes, cylinder and capsule radius and half
  length, sphere radius are all lengths), ``pos → s pos``, ``quat`` unchanged; a mesh geom's vertices ``s v``;
* rest poses: the same rotations with the same probabilities (a quasi-static estimate from solid angles,
  which do not depend on size);
* grasps: ``T = [R | t] → [R | s t]``, widths ``w → s w`` (every family is a pinch of the same faces at the
  same relative place: a fixed depth such as the cuboid's 2 cm sink-in scales with the rest). The hand does not
  scale: a household object's families were filtered for the gripper hitting the object's other parts at the
  inner size, and that filter is not run again at this one;
* ``volume → s³ volume``; ``contains(p) = inner.contains(p / s)``; ``lowest_point(R) = s · inner.lowest_point(R)``;
* mass: a shape whose mass is ``density × volume`` (``Shape.mass``) keeps its density, ``clip(density · s³ V,
  MASS_RANGE)``; a shape with its own mass (an imported object: the manifest's) keeps its mean density,
  ``clip(s³ · inner.mass(), MASS_RANGE)``; ``MASS_RANGE`` is ``inner``'s.

It keeps ``inner``'s ``name`` (tasks and records name objects by it), ``axisymmetric``, ``density`` and
``MASS_RANGE``. ``dims()`` is ``inner.dims()`` plus ``"scale": s``; ``shapes.shape_from_dims`` rebuilds it.
``ScaledShape(ScaledShape(x, a), b)`` is ``ScaledShape(x, a·b)``.

**grasps_verified.** An imported object's grasps were each checked in physics with the real Panda hand at the
imported size. Scaling moves the contacts with the object, but not the hand: the pads stay 2 cm wide, the
fingers 5 cm deep and the opening 8 cm, so a grasp of a mug's handle or of a narrow slot that held at scale 1
may not fit, or may hit the object's other parts, at scale 0.7; the mass and inertia the check lifted change
too. A scaled grasp was therefore not verified: ``grasps_verified`` is ``inner.grasps_verified`` only at
``s == 1`` (the same object), False otherwise. (The oracle then also tries each such grasp tilted by ±30° about
its closing axis, as for the closed-form families: more candidates, none claimed checked.)

**GIGA's sizes** (``kgn_bench.giga``). ``giga_sized(shape, f)``: first the object is shrunk, if needed, so that
the second-largest extent of its oriented bounding box is at most ``MAX_EXTENT`` = 7 cm (it fits the Panda
hand's 8 cm opening one way); an object already that small is left as it is; then by the arrangement's
factor ``f``: ``s = min(1, MAX_EXTENT / e₂) · f``. The extents ``e₁ ≥ e₂ ≥ e₃`` are those of the
minimum-volume oriented bounding box of the visual mesh (``trimesh``'s ``bounding_box_oriented``), not of the
box aligned with the object frame's axes: they do not depend on how the source file happened to orient the
object (a box modelled at 45° about z has the extents of the box), which is what the hand meets.
``shapes.giga_objects`` draws a round's objects before its scene is built (it sits with ``shapes.sample_shape``,
which it calls): the factor is ~U(``PILE_SCALE``) for a pile and ~U(``PACKED_SCALE``) for a packed round
(``giga_scale_range``), one draw per object; ``giga_names`` draws their names as GIGA does, uniformly with
replacement.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import trimesh

from kgn_bench.giga import MAX_EXTENT, OBJECTS_PER_ROUND, PACKED_SCALE, PACKED_TRIES, PILE_SCALE
from kgn_bench.grasp import GraspSet
from kgn_bench.shapes.base import GeomSpec, GraspDensity, RestPose, Shape

__all__ = ["GIGA_ARRANGEMENTS", "SCALE_KEY", "ScaledShape", "giga_names", "giga_scale_range", "giga_sized",
           "oriented_extents"]

SCALE_KEY = "scale"
"""The key ``ScaledShape.dims`` adds to its inner shape's dims."""

GIGA_ARRANGEMENTS: dict[str, tuple[float, float]] = {"pile": PILE_SCALE, "packed": PACKED_SCALE}
"""GIGA's arrangements and the range of their per-object scale factor (``kgn_bench.giga``)."""


def _scaled_mesh(mesh: trimesh.Trimesh, s: float) -> trimesh.Trimesh:
    """A new mesh with vertices ``s v`` and the same faces (``mesh`` is not modified)."""
    return trimesh.Trimesh(vertices=np.asarray(mesh.vertices) * s, faces=np.array(mesh.faces), process=False)


@dataclass(frozen=True)
class ScaledShape(Shape):
    """``inner`` scaled by ``scale`` (> 0) about its object frame's origin (module doc: the math of each part).
    Object frame: ``inner``'s."""

    inner: Shape
    scale: float

    def __post_init__(self) -> None:
        try:
            s = float(self.scale)
        except (TypeError, ValueError):
            raise ValueError(f"dimension {SCALE_KEY!r} must be a positive number, got {self.scale!r}") from None
        if not (np.isfinite(s) and s > 0.0):
            raise ValueError(f"dimension {SCALE_KEY!r} must be a positive number, got {self.scale!r}")
        if isinstance(self.inner, ScaledShape):  # one level: the scales multiply
            s *= self.inner.scale
            object.__setattr__(self, "inner", self.inner.inner)
        object.__setattr__(self, "scale", s)

    # What the inner shape's class says of itself, per instance here.
    @property
    def name(self) -> str:  # type: ignore[override]
        return self.inner.name

    @property
    def axisymmetric(self) -> bool:  # type: ignore[override]
        return self.inner.axisymmetric

    @property
    def density(self) -> float:  # type: ignore[override]
        return self.inner.density

    @property
    def MASS_RANGE(self) -> tuple[float, float]:  # type: ignore[override]
        return self.inner.MASS_RANGE

    @property
    def grasps_verified(self) -> bool:  # type: ignore[override]
        """The inner shape's flag at scale 1 only: a scaled grasp was verified at another size (module doc)."""
        return self.inner.grasps_verified and self.scale == 1.0

    @classmethod
    def sample(cls, rng: np.random.Generator) -> Shape:
        raise TypeError("a ScaledShape wraps a shape (giga_sized, or ScaledShape(shape, s)); it is not sampled")

    @classmethod
    def from_dims(cls, dims: dict) -> Shape:
        raise TypeError(f"a ScaledShape is rebuilt by name: shapes.shape_from_dims(name, dims) with a {SCALE_KEY!r} "
                        "key in dims")

    def dims(self) -> dict:
        return {**self.inner.dims(), SCALE_KEY: self.scale}

    def _build_mesh(self) -> trimesh.Trimesh:
        return _scaled_mesh(self.inner.mesh(), self.scale)

    def _scaled_geom(self, g: GeomSpec) -> GeomSpec:
        """``g`` scaled: size and position × s, the same orientation, mesh vertices × s (the inner shape's visual
        mesh becomes this shape's, built once)."""
        s = self.scale
        if g.mesh is None:
            mesh = None
        elif g.mesh is self.inner.mesh():
            mesh = self.mesh()
        else:
            mesh = _scaled_mesh(g.mesh, s)
        return replace(g, size=tuple(s * float(v) for v in g.size), pos=tuple(s * float(v) for v in g.pos), mesh=mesh)

    @cached_property
    def _collision(self) -> list[GeomSpec]:
        return [self._scaled_geom(g) for g in self.inner.collision_geoms()]

    @cached_property
    def _visual(self) -> list[GeomSpec]:
        inner_collision, inner_visual = self.inner.collision_geoms(), self.inner.visual_geoms()
        if inner_visual == inner_collision and all(
                a.mesh is b.mesh for a, b in zip(inner_visual, inner_collision)):
            return self._collision  # the inner shape renders its collision geoms: so does this one
        return [self._scaled_geom(g) for g in inner_visual]

    def collision_geoms(self) -> list[GeomSpec]:
        return list(self._collision)

    def visual_geoms(self) -> list[GeomSpec]:
        return list(self._visual)

    def rest_poses(self) -> list[RestPose]:
        return self.inner.rest_poses()

    def grasps(self, density: GraspDensity) -> GraspSet:
        """The inner shape's grasps at this size: positions ``s t``, widths ``s w``, orientations unchanged."""
        g = self.inner.grasps(density)
        poses = np.array(g.poses, dtype=float)
        poses[:, :3, 3] *= self.scale
        return GraspSet(poses, np.asarray(g.widths, dtype=float) * self.scale, np.array(g.collides))

    def volume(self) -> float:
        return float(self.scale**3 * self.inner.volume())

    def mass(self) -> float:
        """``clip(density · s³ V)`` for a shape massed by density, else ``clip(s³ · inner.mass())`` (module doc)."""
        if type(self.inner).mass is Shape.mass:
            return super().mass()
        lo, hi = self.MASS_RANGE
        return float(np.clip(self.scale**3 * self.inner.mass(), lo, hi))

    def contains(self, points: np.ndarray) -> np.ndarray:
        return self.inner.contains(np.asarray(points, dtype=float).reshape(-1, 3) / self.scale)

    def lowest_point(self, R: np.ndarray) -> float:
        return float(self.scale * self.inner.lowest_point(R))


def oriented_extents(shape: Shape) -> np.ndarray:
    """(3,) the extents (m), largest first, of the minimum-volume oriented bounding box of ``shape``'s visual
    mesh (frame-independent)."""
    return np.sort(np.asarray(shape.mesh().bounding_box_oriented.primitive.extents, dtype=float))[::-1]


def giga_sized(shape: Shape, factor: float) -> ScaledShape:
    """``shape`` at GIGA's size: ``ScaledShape(shape, min(1, MAX_EXTENT / e₂) · factor)`` with ``e₂`` the
    second-largest oriented extent (``oriented_extents``; module doc). Always a ``ScaledShape``, also when the
    scale comes out 1, so that every object of a GIGA round records its scale."""
    if not (np.isfinite(factor) and factor > 0.0):
        raise ValueError(f"the scale factor must be a positive number, got {factor!r}")
    e2 = float(oriented_extents(shape)[1])
    return ScaledShape(shape, min(1.0, MAX_EXTENT / e2) * float(factor))


def giga_scale_range(arrangement: str) -> tuple[float, float]:
    """The range of GIGA's per-object scale factor for ``arrangement`` ("pile" or "packed"); ``ValueError`` else."""
    try:
        return GIGA_ARRANGEMENTS[arrangement]
    except KeyError:
        raise ValueError(f"unknown GIGA arrangement {arrangement!r} (known: {', '.join(GIGA_ARRANGEMENTS)})") from None


def giga_names(object_set: Sequence[str], arrangement: str, rng: np.random.Generator,
               count: int = OBJECTS_PER_ROUND) -> list[str]:
    """The names of a GIGA round, drawn uniformly with replacement from ``object_set``: ``count`` objects for a
    pile; ``PACKED_TRIES`` candidates for a packed round (``sim.placement.giga_pack`` tries them in order until
    ``count`` stand; each of GIGA's tries draws its own object, so drawing them all first is the same law)."""
    giga_scale_range(arrangement)
    if not object_set:
        raise ValueError("an empty object set")
    if arrangement == "packed" and not 1 <= count <= PACKED_TRIES:
        raise ValueError(f"a packed round stands 1 to {PACKED_TRIES} objects, not {count}")
    n = count if arrangement == "pile" else PACKED_TRIES
    return [object_set[k] for k in rng.integers(0, len(object_set), size=n)]
