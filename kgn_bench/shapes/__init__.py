"""Object shapes: the six Primitive Shape (PS) objects, the household objects of the closed loop, their meshes,
geoms and grasp families.

``PRIMITIVES`` is the training set (the dataset generator and the vision metrics use it alone); ``HOUSEHOLD``
holds the closed-loop objects that never appear in training data; ``OBJECTS`` is both. Any other name is an
imported object (``shapes.library``: a folder with a mesh, its collision hulls and verified grasps).
``sample_shape``/``shape_from_dims`` build a shape of any of them by name; ``is_known`` tells a name exists.
``ScaledShape`` (``shapes.scaled``) is any of them scaled uniformly; it keeps the name, and its dims are the inner
shape's plus a ``"scale"`` key, which ``shape_from_dims`` reads. ``giga_objects`` draws the objects of a GIGA
round by name, at GIGA's sizes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kgn_bench.shapes.base import EVAL_DENSITY, TRAIN_DENSITY, GeomSpec, GraspDensity, RestPose, Shape
from kgn_bench.shapes.household import HOUSEHOLD_CLASSES
from kgn_bench.shapes.library import find_object, list_objects, load_object
from kgn_bench.shapes.mesh_object import MeshObject, ObjectError
from kgn_bench.shapes.primitives import Cuboid, Cylinder, Ring, SemiSphere, Sphere, Stick
from kgn_bench.shapes.scaled import SCALE_KEY, ScaledShape, giga_scale_range, giga_sized

__all__ = [
    "EVAL_DENSITY",
    "HOUSEHOLD",
    "OBJECTS",
    "PRIMITIVES",
    "TRAIN_DENSITY",
    "GeomSpec",
    "GraspDensity",
    "MeshObject",
    "ObjectError",
    "RestPose",
    "ScaledShape",
    "Shape",
    "giga_objects",
    "is_known",
    "known_names",
    "sample_shape",
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


def is_known(name: str) -> bool:
    """Whether ``name`` is a built-in object type or an imported object in the library."""
    return name in OBJECTS or find_object(name) is not None


def known_names() -> list[str]:
    """Every name a task may use: the built-in types, then the imported objects."""
    return [*OBJECTS, *(n for n in list_objects() if n not in OBJECTS)]


def sample_shape(name: str, rng) -> Shape:
    """A shape of type ``name`` with sizes drawn from ``rng`` (an imported object has one size and draws
    nothing)."""
    if name in OBJECTS:
        return OBJECTS[name].sample(rng)
    return load_object(name)


def shape_from_dims(name: str, dims: dict) -> Shape:
    """Rebuild a shape from its stored type name and dimensions (an imported object from its folder); dims with a
    ``"scale"`` key (``ScaledShape.dims``) give the shape of the other dims, scaled by it."""
    if isinstance(dims, dict) and SCALE_KEY in dims:
        return ScaledShape(shape_from_dims(name, {k: v for k, v in dims.items() if k != SCALE_KEY}), dims[SCALE_KEY])
    if name in OBJECTS:
        return OBJECTS[name].from_dims(dims)
    if find_object(name) is None:
        raise ValueError(f"unknown object type {name!r}: not built in ({', '.join(OBJECTS)}) and not an imported "
                         "object (kgn-bench objects list)")
    try:
        return load_object(name)
    except ObjectError as e:
        raise ValueError(str(e)) from None


def giga_objects(names: Sequence[str], arrangement: str, rng: np.random.Generator) -> list[ScaledShape]:
    """One shape per name, in order, at GIGA's size for ``arrangement`` ("pile" or "packed"; ``shapes.scaled``):
    the shape (``sample_shape``: a primitive's sizes drawn from ``rng``, an imported object as it is), then
    ``giga_sized`` with a factor ~U(``giga.PILE_SCALE``) or ~U(``giga.PACKED_SCALE``) drawn from ``rng``. Call it
    before the scene is built, which compiles the sizes; ``shapes.scaled.giga_names`` draws the names."""
    lo, hi = giga_scale_range(arrangement)
    out = []
    for name in names:
        shape = sample_shape(name, rng)
        out.append(giga_sized(shape, float(rng.uniform(lo, hi))))
    return out
