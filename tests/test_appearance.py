"""Procedural appearance: textures and colours per object and for the table change the RGB render only."""

from __future__ import annotations

import numpy as np
import pytest

from kgn_bench.camera import orbit_pose
from kgn_bench.geometry import make_pose
from kgn_bench.shapes import Cuboid, Cylinder
from kgn_bench.sim.appearance import KINDS, Texture, apply_appearance, random_appearance
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.scene import Scene, SceneObject


def _objects():
    return [SceneObject(Cuboid((0.05, 0.06, 0.07)), (0.8, 0.2, 0.2), make_pose(t=[-0.07, 0, 0.035])),
            SceneObject(Cylinder(0.03, 0.08), (0.2, 0.2, 0.8), make_pose(t=[0.07, 0, 0.04]))]


def _render(extend=None):
    scene = Scene(_objects(), extend=extend)
    with SceneRenderer(scene) as r:
        return r.render(orbit_pose(0.7, np.deg2rad(60), 0.0)), scene


def test_random_appearance_is_seeded_and_varied():
    a, b = random_appearance(50, np.random.default_rng(3)), random_appearance(50, np.random.default_rng(3))
    assert a == b and len(a.objects) == 50
    assert {t.kind for t in a.objects} == set(KINDS) and any(t.dots > 0 for t in a.objects)
    assert any(t.dots == 0 for t in a.objects)
    assert len({t.rgb1 for t in a.objects}) == 50


def test_textures_change_the_colours_and_nothing_else():
    plain, _ = _render()
    looks = random_appearance(2, np.random.default_rng(0))
    textured, scene = _render(lambda root: apply_appearance(root, looks))
    np.testing.assert_array_equal(textured.depth, plain.depth)
    np.testing.assert_array_equal(textured.mask, plain.mask)
    for i in (1, 2):  # each object's pixels change colour
        on = plain.mask == i
        assert np.abs(textured.rgb[on].astype(int) - plain.rgb[on].astype(int)).mean() > 10
    table = plain.mask == 0
    assert np.abs(textured.rgb[table].astype(int) - plain.rgb[table].astype(int)).mean() > 5
    assert scene.model.ntex == 3 and scene.model.nmat >= 3


def test_a_checker_object_shows_both_colours():
    red, blue = (0.9, 0.1, 0.1), (0.1, 0.1, 0.9)
    looks = random_appearance(2, np.random.default_rng(0))
    looks = type(looks)((Texture("checker", red, blue, repeat=40.0), looks.objects[1]), looks.table)
    view, _ = _render(lambda root: apply_appearance(root, looks))
    pixels = view.rgb[view.mask == 1].astype(int)
    reddish = (pixels[:, 0] > pixels[:, 2] + 40).mean()
    bluish = (pixels[:, 2] > pixels[:, 0] + 40).mean()
    assert reddish > 0.2 and bluish > 0.2


def test_bad_textures_and_counts_are_refused():
    with pytest.raises(ValueError, match="kind"):
        Texture("marble", (0, 0, 0), (1, 1, 1))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        Texture("flat", (2, 0, 0), (1, 1, 1))
    with pytest.raises(ValueError, match="repeat"):
        Texture("flat", (0, 0, 0), (1, 1, 1), repeat=0.0)
    looks = random_appearance(3, np.random.default_rng(0))
    with pytest.raises(ValueError, match="appearance for 3 objects, the scene has 2"):
        _render(lambda root: apply_appearance(root, looks))
