"""Randomised appearance of a scene: procedural textures and colours per object and for the table.

The paper's objects have uniform colours, so an RGB-D network can learn to find them by colour alone; varied
appearance makes it look at shape. Every texture here is one of MuJoCo's builtin procedural ones, generated
when the model compiles (nothing is downloaded or stored):

- ``flat``: one colour ``rgb1``;
- ``checker``: squares of ``rgb1`` and ``rgb2``;
- ``gradient``: ``rgb1`` blending into ``rgb2``;

each optionally sprinkled with ``rgb2``-coloured random dots (``mark="random"``, a fraction ``dots`` of the
texels). They are cube textures (``type="cube"``), which MuJoCo maps onto any geom by the direction from the
geom's centre, so meshes without texture coordinates take them too; the table's is a 2D texture laid on its
top (a cube texture's dots would streak across a large flat box). ``repeat`` sets how many times the pattern
repeats per metre (``texrepeat`` with ``texuniform``, so that squares stay square). Colours are drawn in
HSV: any hue, saturation U(0.1, 0.9), value U(0.25, 0.95), so dark, light, grey and vivid objects all occur.
The table draws from the same kinds, with duller colours (saturation U(0, 0.4), value U(0.3, 0.8)).

Applied to a compiled scene's MJCF through ``Scene(extend=...)`` (``apply_appearance``): object ``i``'s geoms
(``object_i_*``) and the table get a material each. Geometry, physics and labels are untouched: appearance
changes only the RGB render.
"""

from __future__ import annotations

import colorsys
from dataclasses import dataclass

import numpy as np

__all__ = ["KINDS", "SceneAppearance", "Texture", "apply_appearance", "random_appearance", "random_texture"]

KINDS = ("flat", "checker", "gradient")
"""MuJoCo's builtin procedural textures used here."""
TEXTURE_SIZE = 64
"""Texels along each side of a cube texture's face (small: compiled into every scene)."""


@dataclass(frozen=True)
class Texture:
    """One material: ``kind`` (``KINDS``), colours ``rgb1`` and ``rgb2`` in [0, 1], ``dots`` (the fraction of
    texels turned ``rgb2``; 0 = none), ``repeat`` (pattern repetitions per metre) and ``specular``."""

    kind: str
    rgb1: tuple[float, float, float]
    rgb2: tuple[float, float, float]
    dots: float = 0.0
    repeat: float = 1.0
    specular: float = 0.2

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"texture kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if not all(0.0 <= c <= 1.0 for c in (*self.rgb1, *self.rgb2, self.dots, self.specular)):
            raise ValueError("texture colours, dots and specular must lie in [0, 1]")
        if not self.repeat > 0:
            raise ValueError(f"texture repeat must be positive, got {self.repeat}")


@dataclass(frozen=True)
class SceneAppearance:
    """The material of every object (in scene order) and of the table."""

    objects: tuple[Texture, ...]
    table: Texture


def _hsv(rng: np.random.Generator, saturation: tuple[float, float], value: tuple[float, float]
         ) -> tuple[float, float, float]:
    rgb = colorsys.hsv_to_rgb(rng.uniform(0.0, 1.0), rng.uniform(*saturation), rng.uniform(*value))
    return tuple(round(float(c), 4) for c in rgb)


def random_texture(rng: np.random.Generator, saturation: tuple[float, float] = (0.1, 0.9),
                   value: tuple[float, float] = (0.25, 0.95)) -> Texture:
    """A texture of a uniformly drawn kind with HSV colours in the given ranges, dots on half of them."""
    kind = KINDS[int(rng.integers(len(KINDS)))]
    rgb1, rgb2 = _hsv(rng, saturation, value), _hsv(rng, saturation, value)
    dots = round(float(rng.uniform(0.02, 0.2)), 3) if rng.random() < 0.5 else 0.0
    repeat = round(float(rng.choice([4.0, 8.0, 16.0, 32.0])), 1)
    return Texture(kind, rgb1, rgb2, dots, repeat, round(float(rng.uniform(0.0, 0.5)), 3))


def random_appearance(objects: int, rng: np.random.Generator) -> SceneAppearance:
    """Independent textures for ``objects`` objects and a duller one for the table (module docstring)."""
    return SceneAppearance(tuple(random_texture(rng) for _ in range(objects)),
                           random_texture(rng, saturation=(0.0, 0.4), value=(0.3, 0.8)))


def _material(asset, name: str, texture: Texture, mapping: str = "cube") -> str:
    asset.add("texture", name=f"{name}_tex", type=mapping, builtin=texture.kind, rgb1=texture.rgb1,
              rgb2=texture.rgb2, mark="random" if texture.dots > 0 else "none", random=texture.dots,
              markrgb=texture.rgb2, width=TEXTURE_SIZE, height=TEXTURE_SIZE)
    asset.add("material", name=f"{name}_mat", texture=f"{name}_tex", texrepeat=(texture.repeat, texture.repeat),
              texuniform=True, specular=texture.specular, rgba=(1.0, 1.0, 1.0, 1.0))
    return f"{name}_mat"


def apply_appearance(root, appearance: SceneAppearance) -> None:
    """Give the MJCF ``root`` of a scene (``sim.scene.build_mjcf``) the materials of ``appearance``: object
    ``i``'s geoms ``object_i_*`` and the table geom. ``ValueError`` if the counts of objects differ."""
    bodies = [b for b in root.worldbody.body if b.name and b.name.startswith("object_")]
    if len(bodies) != len(appearance.objects):
        raise ValueError(f"appearance for {len(appearance.objects)} objects, the scene has {len(bodies)}")
    for body, texture in zip(bodies, appearance.objects):
        material = _material(root.asset, body.name, texture)
        for geom in body.geom:
            geom.material = material
            geom.rgba = None
    table = root.find("geom", "table")
    table.material = _material(root.asset, "table", appearance.table, mapping="2d")
    table.rgba = None
