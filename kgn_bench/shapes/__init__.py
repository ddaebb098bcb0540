"""Object shapes: the six Primitive Shape (PS) objects, the household objects of the closed loop, their meshes,
geoms and grasp families.

``PRIMITIVES`` is the training set (the dataset generator and the vision metrics use it alone); ``HOUSEHOLD``
holds the closed-loop objects that never appear in training data; ``OBJECTS`` is both, and
``shape_class``/``shape_from_dims`` look names up there.
"""

from __future__ import annotations

from kgn_bench.shapes.base import EVAL_DENSITY, TRAIN_DENSITY, GeomSpec, GraspDensity, RestPose, Shape
from kgn_bench.shapes.household import HOUSEHOLD_CLASSES
from kgn_bench.shapes.primitives import Cuboid, Cylinder, Ring, SemiSphere, Sphere, Stick

__all__ = [
    "EVAL_DENSITY",
    "HOUSEHOLD",
    "OBJECTS",
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

HOUSEHOLD: dict[str, type[Shape]] = {cls.name: cls for cls in HOUSEHOLD_CLASSES}
"""The household objects (closed loop only, never in training data), in a fixed order."""

OBJECTS: dict[str, type[Shape]] = {**PRIMITIVES, **HOUSEHOLD}
"""Every known object type: the PS shapes, then the household objects."""


def shape_class(name: str) -> type[Shape]:
    """The shape class registered under ``name``; ``ValueError`` names the known ones otherwise."""
    try:
        return OBJECTS[name]
    except KeyError:
        raise ValueError(f"unknown object type {name!r}; known: {', '.join(OBJECTS)}") from None


def shape_from_dims(name: str, dims: dict) -> Shape:
    """Rebuild a shape from its stored type name and dimensions."""
    return shape_class(name).from_dims(dims)
