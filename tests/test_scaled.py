"""ScaledShape: every part of a shape scaled about its origin, rebuilt from its dims, compiled in MuJoCo; GIGA's
object sizes (giga_sized, giga_names)."""

import json

import mujoco
import numpy as np
import pytest

from kgn_bench.giga import MAX_EXTENT, PACKED_TRIES
from kgn_bench.shapes import EVAL_DENSITY, PRIMITIVES, TRAIN_DENSITY, ScaledShape, shape_from_dims
from kgn_bench.shapes.library import load_object
from kgn_bench.shapes.primitives import Cuboid, Cylinder, Sphere
from kgn_bench.shapes.scaled import giga_names, giga_sized, oriented_extents
from kgn_bench.sim.scene import Scene, SceneObject


def test_a_scaled_box_scales_its_geoms_mesh_volume_mass_and_grasps():
    box = Cuboid((0.10, 0.06, 0.08))
    inner_vertices = box.mesh().vertices.copy()
    s = 0.5
    small = ScaledShape(box, s)
    assert small.name == "cuboid" and not small.axisymmetric
    (geom,) = small.collision_geoms()
    assert geom.kind == "box" and geom.size == pytest.approx((0.025, 0.015, 0.02))
    assert small.visual_geoms() == small.collision_geoms()
    assert small.volume() == pytest.approx(0.10 * 0.06 * 0.08 * s**3)
    # density × scaled volume (500 × 6e-5 = 0.03 kg), within the cuboid's mass range
    assert small.mass() == pytest.approx(np.clip(500.0 * small.volume(), *box.MASS_RANGE))
    # a big box's mass is clipped (500 × 1.7e-3 m³ = 0.86 kg → 0.4 kg), its scaled copy's is its density's again
    assert ScaledShape(Cuboid((0.12, 0.12, 0.12)), 0.6).mass() == pytest.approx(500.0 * 0.12**3 * 0.6**3)
    np.testing.assert_allclose(small.mesh().vertices, inner_vertices * s)
    np.testing.assert_array_equal(box.mesh().vertices, inner_vertices)  # the inner mesh is not touched
    R = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    assert small.lowest_point(R) == pytest.approx(-0.015)
    np.testing.assert_array_equal(small.contains(np.array([[0.024, 0.0, 0.0], [0.026, 0.0, 0.0]])), [True, False])
    assert [r.R.tolist() for r in small.rest_poses()] == [r.R.tolist() for r in box.rest_poses()]
    g, g0 = small.grasps(TRAIN_DENSITY), box.grasps(TRAIN_DENSITY)
    np.testing.assert_allclose(g.poses[:, :3, 3], s * g0.poses[:, :3, 3])
    np.testing.assert_array_equal(g.poses[:, :3, :3], g0.poses[:, :3, :3])
    np.testing.assert_allclose(g.widths, s * g0.widths)
    assert not small.grasps_verified


def test_a_scaled_tube_compiles_with_its_mass_and_scaled_pieces():
    tube = Cylinder(0.05, 0.08)
    s = 0.7
    scaled = ScaledShape(tube, s)
    for a, b in zip(scaled.collision_geoms(), tube.collision_geoms()):
        assert a.size == pytest.approx(tuple(s * v for v in b.size))
        assert a.pos == pytest.approx(tuple(s * v for v in b.pos))
        assert a.quat == b.quat
    (visual,) = scaled.visual_geoms()
    assert visual.mesh is scaled.mesh()
    np.testing.assert_allclose(visual.mesh.vertices, s * tube.mesh().vertices)
    scene = Scene([SceneObject(scaled, (0.5, 0.5, 0.5))])
    assert scene.model.body_mass[scene.body_ids[0]] == pytest.approx(scaled.mass(), rel=1e-6)
    first = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "object_0_col0")
    np.testing.assert_allclose(scene.model.geom_size[first], s * np.asarray(tube.collision_geoms()[0].size))


@pytest.mark.parametrize("name", list(PRIMITIVES))
def test_dims_rebuild_the_scaled_shape(name, rng):
    shape = ScaledShape(PRIMITIVES[name].sample(rng), 0.8)
    dims = json.loads(json.dumps(shape.dims()))
    assert dims["scale"] == 0.8
    again = shape_from_dims(name, dims)
    assert again == shape and isinstance(again, ScaledShape)
    assert again.grasps(EVAL_DENSITY).poses.shape == shape.grasps(EVAL_DENSITY).poses.shape
    assert shape_from_dims(name, shape.inner.dims()) == shape.inner  # without the key: the shape as it was


def test_scales_multiply_and_bad_ones_are_named():
    box = Cuboid((0.1, 0.1, 0.1))
    twice = ScaledShape(ScaledShape(box, 0.5), 0.8)
    assert twice.inner is box and twice.scale == pytest.approx(0.4)
    for bad in (0.0, -1.0, float("nan"), "big", None):
        with pytest.raises(ValueError, match="scale"):
            shape_from_dims("cuboid", {"size": [0.1, 0.1, 0.1], "scale": bad})
    with pytest.raises(TypeError):
        ScaledShape.sample(np.random.default_rng(0))
    with pytest.raises(TypeError):
        ScaledShape.from_dims({"size": [0.1, 0.1, 0.1], "scale": 0.5})


def test_a_big_mesh_object_is_shrunk_to_seven_centimetres():
    obj = load_object("pb_000")
    assert oriented_extents(obj)[1] > MAX_EXTENT  # the test needs an object too wide for the hand
    hull = obj.hulls[0].vertices.copy()
    sized = giga_sized(obj, 1.0)
    e = oriented_extents(sized)
    assert e[1] == pytest.approx(MAX_EXTENT, rel=1e-3)
    packed = giga_sized(obj, 0.8)
    assert oriented_extents(packed)[1] == pytest.approx(0.8 * MAX_EXTENT, rel=1e-3)
    assert packed.name == "pb_000" and packed.dims() == {"object": "pb_000", "scale": packed.scale}
    assert shape_from_dims("pb_000", packed.dims()) == packed
    # the manifest's mass × s³ (within the imported objects' range), the hulls scaled, the object's untouched
    assert packed.mass() == pytest.approx(np.clip(obj.mass() * packed.scale**3, *obj.MASS_RANGE))
    assert len(packed.collision_geoms()) == len(obj.hulls)
    np.testing.assert_allclose(packed.collision_geoms()[0].mesh.vertices, packed.scale * hull)
    np.testing.assert_array_equal(obj.hulls[0].vertices, hull)
    # verified at the imported size only
    assert obj.grasps_verified and not packed.grasps_verified and ScaledShape(obj, 1.0).grasps_verified
    g = packed.grasps(EVAL_DENSITY)
    np.testing.assert_allclose(g.widths, packed.scale * obj.grasps(EVAL_DENSITY).widths)


def test_a_small_object_keeps_its_size_before_the_factor():
    ball = Sphere(0.02)
    assert giga_sized(ball, 0.75).scale == 0.75
    assert giga_sized(ball, 1.0).scale == 1.0
    with pytest.raises(ValueError, match="factor"):
        giga_sized(ball, 0.0)


def test_giga_rounds_draw_names_with_replacement():
    names = giga_names(["cuboid", "sphere"], "pile", np.random.default_rng(3), count=20)
    assert len(names) == 20 and set(names) == {"cuboid", "sphere"}  # 20 from 2: drawn with replacement
    assert giga_names(["cuboid", "sphere"], "pile", np.random.default_rng(3), count=20) == names
    assert len(giga_names(list(PRIMITIVES), "packed", np.random.default_rng(3))) == PACKED_TRIES
    with pytest.raises(ValueError, match="arrangement"):
        giga_names(["cuboid"], "spread", np.random.default_rng(0))
    with pytest.raises(ValueError, match="packed"):
        giga_names(["cuboid"], "packed", np.random.default_rng(0), count=PACKED_TRIES + 1)
