"""Grasp-family geometry, sizes, meshes and hollow collision geometry of the six PS shapes."""

import numpy as np
import pytest

from kgn_bench.shapes import EVAL_DENSITY, PRIMITIVES, TRAIN_DENSITY, GraspDensity, shape_from_dims
from kgn_bench.shapes.primitives import WALL_RATIO, Cuboid, Cylinder, Ring, SemiSphere, Sphere, Stick

EXPECTED_COUNTS = {  # the reference implementation's counts (train 5/11, test 10/30)
    "cuboid": (60, 120),
    "cylinder": (77, 360),
    "ring": (22, 60),
    "stick": (55, 300),
    "sphere": (22, 60),
    "semi_sphere": (11, 30),
}


@pytest.mark.parametrize("name", list(PRIMITIVES))
def test_counts_rotations_and_sizes(name, rng):
    cls = PRIMITIVES[name]
    shape = cls.sample(rng)
    train, test = shape.grasps(TRAIN_DENSITY), shape.grasps(EVAL_DENSITY)
    assert (len(train), len(test)) == EXPECTED_COUNTS[name]
    R = test.poses[:, :3, :3]
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0)
    # unique poses: no duplicated angle endpoint
    flat = np.round(test.poses.reshape(len(test), -1), 9)
    assert len(np.unique(flat, axis=0)) == len(test)
    assert shape_from_dims(name, shape.dims()) == shape
    mesh = shape.mesh()
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(shape.volume(), rel=0.03)
    assert sum(r.probability for r in shape.rest_poses()) == pytest.approx(1.0)
    lo, hi = shape.MASS_RANGE
    assert lo <= shape.mass() <= hi


def test_bad_dims_and_unknown_types_are_named():
    with pytest.raises(ValueError, match="unknown object type 'teapot'"):
        shape_from_dims("teapot", {})
    with pytest.raises(ValueError, match="r_in"):
        shape_from_dims("cylinder", {"r_in": -1, "h": 0.1})
    with pytest.raises(ValueError, match="size"):
        shape_from_dims("cuboid", {"size": [0.1, 0.1]})


def test_cuboid_family_sinks_2cm_and_closes_along_box_axes():
    box = Cuboid((0.10, 0.06, 0.08))
    g = box.grasps(TRAIN_DENSITY)
    d = np.array(box.size)
    for T, w in zip(g.poses, g.widths):
        x_g, z_g, t = T[:3, 0], T[:3, 2], T[:3, 3]
        app = int(np.argmax(np.abs(x_g)))
        close = int(np.argmax(np.abs(z_g)))
        assert abs(x_g[app]) == 1 and z_g[close] == 1  # axis-aligned, positive closing axis
        # the midpoint is 2 cm inside the face the gripper enters through
        entry_face = -np.sign(x_g[app]) * d[app] / 2
        assert abs(t[app] - entry_face) == pytest.approx(0.02)
        assert np.all(np.abs(t) < d / 2)
        assert t[close] == 0.0
        assert w == pytest.approx(1.2 * d[close])
    # along the grasp's y axis: the interior fractions ±1/3, ±1/6, 0 of the extent
    top = g.poses[(g.poses[:, 2, 0] == -1) & (g.poses[:, 0, 2] == 1)]  # approach −Z, closing +X
    np.testing.assert_allclose(np.sort(top[:, 1, 3]), np.array([-1 / 3, -1 / 6, 0, 1 / 6, 1 / 3]) * 0.06, atol=1e-12)


@pytest.mark.parametrize("cls", [Cylinder, Ring])
def test_rim_grasps_sit_inside_the_wall_and_close_radially(cls, rng):
    s = cls.sample(rng)
    g = s.grasps(GraspDensity(3, 12))
    rim = g.poses[np.abs(g.poses[:, 2, 0]) > 0.99]  # vertical approach
    assert len(rim) == 24
    t = rim[:, :3, 3]
    radius = np.hypot(t[:, 0], t[:, 1])
    np.testing.assert_allclose(radius, 0.5 * (s.r_in + s.r_out))
    np.testing.assert_allclose(np.abs(t[:, 2]), s.h / 2 - 0.005)
    # top grasps approach downward from z > 0, bottom ones upward from z < 0
    np.testing.assert_array_equal(np.sign(rim[:, 2, 0]), -np.sign(t[:, 2]))
    radial = t[:, :2] / radius[:, None]
    closing = rim[:, :2, 2]
    np.testing.assert_allclose(np.abs(np.sum(radial * closing, axis=1)), 1.0, atol=1e-12)
    assert np.all(s.contains(t))
    np.testing.assert_allclose(g.widths[: len(rim)], 5 * (WALL_RATIO - 1) * s.r_in)


@pytest.mark.parametrize("cls", [Cylinder, Stick])
def test_side_grasps_are_on_the_axis_with_horizontal_closing(cls, rng):
    s = cls.sample(rng)
    g = s.grasps(GraspDensity(4, 9))
    side = g.poses[np.abs(g.poses[:, 2, 0]) < 1e-9]
    assert len(side) == 36
    np.testing.assert_allclose(side[:, :2, 3], 0.0, atol=1e-12)  # on the axis
    np.testing.assert_allclose(np.unique(np.round(side[:, 2, 3], 12)), np.linspace(-s.h / 2, s.h / 2, 6)[1:-1])
    np.testing.assert_allclose(side[:, 2, 2], 0.0, atol=1e-12)  # closing axis horizontal
    np.testing.assert_allclose(np.sum(side[:, :3, 0] * side[:, :3, 2], axis=1), 0.0, atol=1e-12)
    side_w = g.widths[np.abs(g.poses[:, 2, 0]) < 1e-9]
    np.testing.assert_allclose(side_w, 2.4 * WALL_RATIO * s.r_in)


def test_sphere_grasps_pass_through_the_centre():
    s = Sphere(0.04)
    g = s.grasps(TRAIN_DENSITY)
    np.testing.assert_allclose(g.poses[:, :3, 3], 0.0)
    approach_z = g.poses[:, 2, 0]
    assert np.sum(np.isclose(approach_z, -1)) == 11 and np.sum(np.isclose(approach_z, 0)) == 11
    np.testing.assert_allclose(g.widths, 0.096)


def test_bowl_grasps_at_the_rim_inside_the_wall():
    s = SemiSphere(0.06)
    g = s.grasps(EVAL_DENSITY)
    t = g.poses[:, :3, 3]
    assert np.all(t[:, 2] == pytest.approx(-0.002))
    dist = np.linalg.norm(t, axis=1)
    assert np.all((dist > s.r_in) & (dist < s.r))
    np.testing.assert_allclose(g.poses[:, 2, 0], -1.0)  # from the top
    radial = t[:, :2] / np.linalg.norm(t[:, :2], axis=1, keepdims=True)
    np.testing.assert_allclose(np.abs(np.sum(radial * g.poses[:, :2, 2], axis=1)), 1.0, atol=1e-12)
    assert np.all(s.contains(t))
    np.testing.assert_allclose(g.widths, 5 * (s.r - s.r / 1.15))


def test_hollow_shapes_are_hollow_and_walls_are_solid():
    tube = Cylinder(0.05, 0.08)
    r_mid = 0.5 * (tube.r_in + tube.r_out)
    ang = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    wall = np.stack([r_mid * np.cos(ang), r_mid * np.sin(ang), np.zeros_like(ang)], 1)
    assert np.all(tube.contains(wall))
    assert not np.any(tube.contains(np.array([[0, 0, 0], [0.9 * tube.r_in, 0, 0.03]])))
    bowl = SemiSphere(0.07)
    rm = 0.5 * (bowl.r + bowl.r_in)
    alpha = np.linspace(0.05, np.pi / 2 - 0.05, 20)
    shell = np.stack([rm * np.sin(alpha) * np.cos(3 * alpha), rm * np.sin(alpha) * np.sin(3 * alpha),
                      -rm * np.cos(alpha)], 1)
    assert np.all(bowl.contains(shell))
    assert not np.any(bowl.contains(np.array([[0, 0, -0.5 * bowl.r_in], [0.02, 0, -0.03]])))


def test_geom_containment_for_every_kind():
    import trimesh

    from kgn_bench.shapes import GeomSpec

    q = (np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0)  # 90° about x: the geom's z axis is the object's −y
    capsule = GeomSpec("capsule", (0.01, 0.03), pos=(0.1, 0.0, 0.0), quat=q)
    pts = np.array([[0.1, 0.039, 0.0], [0.1, -0.039, 0.0], [0.1, 0.041, 0.0], [0.1, 0.0, 0.0099], [0.1, 0, 0.011]])
    np.testing.assert_array_equal(capsule.contains(pts), [True, True, False, True, False])
    box = GeomSpec("box", (0.01, 0.02, 0.03))
    np.testing.assert_array_equal(box.contains(np.array([[0.0, 0.0195, 0.0], [0.0, 0.0, 0.031]])), [True, False])
    tetra = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], faces=[[0, 2, 1], [0, 1, 3],
                                                                                          [0, 3, 2], [1, 2, 3]])
    mesh = GeomSpec("mesh", mesh=tetra)
    np.testing.assert_array_equal(mesh.contains(np.array([[0.1, 0.1, 0.1], [0.5, 0.5, 0.5]])), [True, False])
    with pytest.raises(ValueError, match="plane"):
        GeomSpec("plane").contains(np.zeros((1, 3)))


def test_giga_objects_are_scaled_in_their_arrangement_range():
    from kgn_bench.giga import MAX_EXTENT, PACKED_SCALE, PILE_SCALE
    from kgn_bench.shapes import giga_objects
    from kgn_bench.shapes.scaled import oriented_extents

    for arrangement, (lo, hi) in (("pile", PILE_SCALE), ("packed", PACKED_SCALE)):
        shapes = giga_objects(list(PRIMITIVES) * 2, arrangement, np.random.default_rng(5))
        assert shapes == giga_objects(list(PRIMITIVES) * 2, arrangement, np.random.default_rng(5))
        assert [s.name for s in shapes] == list(PRIMITIVES) * 2
        for shape in shapes:
            assert oriented_extents(shape)[1] <= hi * MAX_EXTENT + 1e-9
            factor = shape.scale / min(1.0, MAX_EXTENT / oriented_extents(shape.inner)[1])
            assert lo <= factor <= hi
            assert shape_from_dims(shape.name, shape.dims()) == shape
    with pytest.raises(ValueError, match="arrangement"):
        giga_objects(["cuboid"], "spread", np.random.default_rng(0))
