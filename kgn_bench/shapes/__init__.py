"""Object shapes: the six Primitive Shape (PS) objects, their meshes, geoms and grasp families."""

from __future__ import annotations

from kgn_bench.shapes.base import EVAL_DENSITY, TRAIN_DENSITY, GeomSpec, GraspDensity, RestPose, Shape
from kgn_bench.shapes.primitives import Cuboid, Cylinder, Ring, SemiSphere, Sphere, Stick

__all__ = [
    "EVAL_DENSITY",
    "PRIMITIVES",
    "TRAIN_DENSITY",
    "GeomSpec",
    "GraspDensity",
    "RestPose",
    "Shape",
    "shape_class",
    "shape_from_dims",
]

PRIMITIVES: dict[str, type[Shape]] = {
    cls.name: cls for cls in (Cuboid, Cylinder, Ring, Stick, Sphere, SemiSphere)
}
"""The PS shapes by their annotation type name, in a fixed order."""


def shape_class(name: str) -> type[Shape]:
    """The shape class registered under ``name``; ``ValueError`` names the known ones otherwise."""
    try:
        return PRIMITIVES[name]
    except KeyError:
        raise ValueError(f"unknown object type {name!r}; known: {', '.join(PRIMITIVES)}") from None


def shape_from_dims(name: str, dims: dict) -> Shape:
    """Rebuild a shape from its stored type name and dimensions."""
    return shape_class(name).from_dims(dims)
