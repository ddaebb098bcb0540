"""Household objects: sizes, meshes, hollow collision geometry, grasp families, settling in MuJoCo,
task files and their separation from the training set."""

import json
from pathlib import Path

import numpy as np
import pytest
import tomllib

from kgn_bench.config import ConfigError, load_task
from kgn_bench.geometry import make_pose, matrix_from_quat_wxyz, rot_z
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes import (
    EVAL_DENSITY,
    HOUSEHOLD,
    OBJECTS,
    PRIMITIVES,
    TRAIN_DENSITY,
    shape_class,
    shape_from_dims,
)
from kgn_bench.shapes.household import PINCH_CLEARANCE, Banana, FootedBowl, Mug

TASKS = Path(__file__).resolve().parents[1] / "tasks"
NAMES = list(HOUSEHOLD)


def _geom_bounds(shape):
    """Axis-aligned bounds (2, 3) of the collision geoms, from their corners/extremes."""
    pts = []
    for g in shape.collision_geoms():
        R = matrix_from_quat_wxyz(np.asarray(g.quat))
        if g.kind == "mesh":
            local = g.mesh.vertices
        elif g.kind == "sphere":
            local = g.size[0] * np.concatenate([np.eye(3), -np.eye(3)])
        else:
            if g.kind == "box":
                half = np.asarray(g.size)
            else:  # cylinder: its bounding box in its own frame
                half = np.array([g.size[0], g.size[0], g.size[1]])
            signs = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
            local = signs * half
        pts.append(local @ R.T + np.asarray(g.pos))
    pts = np.concatenate(pts)
    return np.stack([pts.min(0), pts.max(0)])


# overall extents (x, y, z) the dims promise, in the object frame
EXPECTED_EXTENTS = {
    "mug": lambda s: (2 * s.r_out + s.HANDLE_GAP + 2 * s.HANDLE_RADIUS, 2 * s.r_out, s.h),
    "bottle": lambda s: (2 * s.r, 2 * s.r, s.h),
    "footed_bowl": lambda s: (2 * s.r, 2 * s.r, s.r + FootedBowl.FOOT_DROP),
    "hammer": lambda s: (s.length, s.head, s.head_side),
    "banana": lambda s: (None, None, 2 * s.radius_at(0.5)),
    "c_clamp": lambda s: (None, None, s.thickness),
    "can": lambda s: (2 * s.r, 2 * s.r, s.h),
    "l_bracket": lambda s: (s.a, s.w, s.b),
}


def test_registries_keep_the_training_set_apart():
    assert list(PRIMITIVES) == ["cuboid", "cylinder", "ring", "stick", "sphere", "semi_sphere"]
    assert len(HOUSEHOLD) >= 8 and not set(HOUSEHOLD) & set(PRIMITIVES)
    assert OBJECTS == {**PRIMITIVES, **HOUSEHOLD}
    for name in OBJECTS:
        assert shape_class(name).name == name
    with pytest.raises(ValueError, match=r"unknown object type 'teapot'.*mug"):
        shape_class("teapot")


def test_dataset_generator_draws_primitives_only():
    from kgn_bench.data.generate import GenerateConfig, _sample_objects

    assert GenerateConfig(mode="multi", scenes=5, views=1).manifest()["object_types"] == list(PRIMITIVES)
    seen = set()
    for seed in range(20):
        for mode in ("single", "multi"):
            objs = _sample_objects(GenerateConfig(mode=mode, scenes=5, views=1), np.random.default_rng(seed))
            seen |= {o.shape.name for o in objs}
    assert seen == set(PRIMITIVES)


@pytest.mark.parametrize("name", NAMES)
def test_dims_round_trip_masses_and_rest_poses(name):
    cls = HOUSEHOLD[name]
    lo, hi = cls.MASS_RANGE
    for seed in range(5):
        shape = cls.sample(np.random.default_rng(seed))
        dims = json.loads(json.dumps(shape.dims()))
        assert shape_from_dims(name, dims) == shape
        # realistic masses: in range before clipping at the extremes of the size ranges too
        assert lo <= shape.density * shape.volume() <= hi, (name, shape, shape.density * shape.volume())
        assert lo <= shape.mass() <= hi
        rest = shape.rest_poses()
        assert sum(r.probability for r in rest) == pytest.approx(1.0)
        for r in rest:
            assert r.probability > 0
            np.testing.assert_allclose(r.R @ r.R.T, np.eye(3), atol=1e-9)
            assert np.linalg.det(r.R) == pytest.approx(1.0)
    for key in cls.RANGES:
        bad = {**shape.dims(), key: -0.01}
        with pytest.raises(ValueError, match=key):
            shape_from_dims(name, bad)
        with pytest.raises(ValueError, match=key):
            shape_from_dims(name, {k: v for k, v in shape.dims().items() if k != key})


@pytest.mark.parametrize("name", NAMES)
def test_mesh_matches_collision_geometry_and_dims(name):
    rng = np.random.default_rng(1)
    shape = HOUSEHOLD[name].sample(rng)
    mesh = shape.mesh()
    assert mesh.is_watertight and mesh.volume > 0
    bounds = _geom_bounds(shape)
    np.testing.assert_allclose(mesh.bounds, bounds, atol=3e-3)  # what is drawn is what collides
    extents = mesh.extents
    for axis, expected in enumerate(EXPECTED_EXTENTS[name](shape)):
        if expected is not None:
            assert extents[axis] == pytest.approx(expected, abs=2e-3), (name, axis)
    # volume(): the union of the pieces, by Monte Carlo over the geoms (overlaps counted once)
    points = rng.uniform(bounds[0], bounds[1], size=(60000, 3))
    mc = shape.contains(points).mean() * np.prod(bounds[1] - bounds[0])
    assert shape.volume() == pytest.approx(mc, rel=0.08)


@pytest.mark.parametrize("name", NAMES)
def test_grasp_families_fit_the_gripper_and_hold_the_object(name):
    shape = HOUSEHOLD[name].sample(np.random.default_rng(2))
    points = shape.surface_points()
    lo, hi = _geom_bounds(shape)
    for density in (TRAIN_DENSITY, EVAL_DENSITY):
        g = shape.grasps(density)
        assert len(g) >= 10
        assert np.all(g.widths > PINCH_CLEARANCE) and np.all(g.widths <= GRIPPER.max_width)
        R = g.poses[:, :3, :3]
        np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
        np.testing.assert_allclose(np.linalg.det(R), 1.0)
        t = g.poses[:, :3, 3]
        assert np.all((t >= lo - 1e-3) & (t <= hi + 1e-3)), "grasp origins must lie within the object's bounds"
        # the object lies between the fingers: surface points inside each grasp's closing region
        for pose, w in zip(g.poses[::7], g.widths[::7]):
            region = GRIPPER.closing_region(w)
            local = (points - pose[:3, 3]) @ pose[:3, :3]
            assert np.any(np.all(np.abs(local - region.centre) < region.half, axis=1))
            # ... and no finger sits inside the object at the grasp (fingers at the width, tips at the origin)
            finger = (local[:, 0] > -GRIPPER.finger_length) & (local[:, 0] < 0) \
                & (np.abs(local[:, 1]) < GRIPPER.finger_breadth / 2 - 1e-3) \
                & (np.abs(local[:, 2]) > w / 2 + 1e-3) & (np.abs(local[:, 2]) < w / 2 + GRIPPER.finger_thickness)
            assert not np.any(finger)


def test_mug_and_footed_bowl_are_hollow():
    mug = Mug(r_in=0.035, h=0.09)
    hh = mug.h / 2
    x0, ax, _ = mug._ellipse()
    cavity = np.array([[0, 0, 0], [0, 0, hh - 0.01], [0, 0, -hh + mug.BOTTOM + 0.003], [0.03, 0, 0], [0, -0.03, 0.02]])
    assert not np.any(mug.contains(cavity))
    gap = np.array([[mug.r_out + mug.HANDLE_GAP / 2, 0, 0], [mug.r_out + 0.01, 0, 0.01]])
    assert not np.any(mug.contains(gap))
    solid = np.array([[0.5 * (mug.r_in + mug.r_out), 0, 0], [0, -0.5 * (mug.r_in + mug.r_out), 0.03],
                      [0, 0, -hh + 0.003], [x0 + ax, 0, 0]])
    assert np.all(mug.contains(solid))
    # rim grasps stay clear of the handle
    rim = mug.grasps(EVAL_DENSITY).poses
    rim = rim[np.isclose(rim[:, 2, 0], -1.0)]
    assert len(rim) and np.all(np.abs(np.arctan2(rim[:, 1, 3], rim[:, 0, 3])) >= mug.RIM_HANDLE_CLEARANCE - 1e-9)

    bowl = FootedBowl(r=0.06)
    ri, ro, bottom, top = bowl.foot()
    hollow = np.array([[0, 0, -bowl.r / 2], [0, 0, -0.01], [0, 0, bottom + 0.004], [0.5 * ri, 0, bottom + 0.004]])
    assert not np.any(bowl.contains(hollow))
    walls = np.array([[0.5 * (ri + ro), 0, bottom + 0.004], [0, 0, -bowl.r + 0.003]])
    assert np.all(bowl.contains(walls))
    assert bottom < top < -np.sqrt(bowl.bowl.r_in**2 - ri**2)  # the foot neither floats nor pokes into the bowl


def test_banana_lean_is_its_resting_tilt():
    banana = Banana(R=0.13, angle=1.2, r=0.014)
    assert 0.05 < banana.lean() < np.pi / 2
    assert np.isclose(banana.rest_poses()[0].R[2, 2], np.cos(banana.lean()))


@pytest.mark.parametrize("name", NAMES)
def test_objects_settle_in_every_rest_pose(name):
    """Dropped in a real MuJoCo scene in each rest pose, the object comes to rest on the table near where it
    was put, and the oracle has a collision-free grasp from above for it."""
    from kgn_bench.camera import orbit_pose
    from kgn_bench.detectors.base import Observation
    from kgn_bench.detectors.oracle import OracleDetector
    from kgn_bench.sim.placement import PlacementConfig, settle
    from kgn_bench.sim.scene import Scene, SceneObject

    shape = HOUSEHOLD[name].sample(np.random.default_rng(3))
    cam = orbit_pose(0.8, np.deg2rad(60), np.deg2rad(90))
    for k, rest in enumerate(shape.rest_poses()):
        R = rot_z(0.7) @ rest.R
        start = make_pose(R, (0.05, -0.03, -shape.lowest_point(R) + 0.002))
        scene = Scene([SceneObject(shape, (0.5, 0.5, 0.5), start)])
        stats = settle(scene, PlacementConfig())
        assert stats.sim_time < PlacementConfig().settle_time_max, (name, k, "still moving")
        T = scene.object_pose(0)
        assert np.linalg.norm(T[:2, 3] - start[:2, 3]) < 0.05, (name, k, T[:3, 3])
        low = (shape.mesh().vertices @ T[:3, :3].T + T[:3, 3])[:, 2].min()
        assert abs(low) < 5e-3, (name, k, low)
        before = scene.object_pose(0)
        scene.step(100)
        assert np.abs(scene.object_pose(0)[:3, 3] - before[:3, 3]).max() < 2e-3
        oracle = OracleDetector()
        oracle.attach(scene)
        depth = np.zeros((scene.intrinsics.height, scene.intrinsics.width), np.float32)
        rgb = np.zeros((*depth.shape, 3), np.uint8)
        cands = oracle.detect(Observation(rgb, depth, scene.intrinsics, cam))
        approach_z = cands.world_poses(cam)[:, 2, 0]
        assert np.any(approach_z < -0.5), (name, k, "no grasp from above")


def test_task_files_and_config_names(tmp_path):
    single = load_task(TASKS / "single_household.toml")
    reference = load_task(TASKS / "single_object.toml")
    assert single.protocol == "single_object" and single.objects == tuple(HOUSEHOLD) and single.trials == 15
    assert single.camera == reference.camera and single.selector == reference.selector
    multi = load_task(TASKS / "multi_household.toml")
    assert multi.protocol == "multi_object" and multi.objects_per_scene == 5 and multi.trials == 30
    assert set(multi.objects) == set(HOUSEHOLD) | set(PRIMITIVES)
    assert tomllib.loads((TASKS / "multi_household.toml").read_text())["camera"] == \
        tomllib.loads((TASKS / "multi_object.toml").read_text())["camera"]

    from kgn_bench.bench.trial import trial_objects

    objs = [o for i in range(0, single.n_trials, single.trials)
            for o in trial_objects(single, i, np.random.default_rng(i))]
    assert [o.shape.name for o in objs] == list(HOUSEHOLD)

    p = tmp_path / "t.toml"
    p.write_text('[task]\nname = "t"\nprotocol = "single_object"\n[objects]\nset = ["mug", "cuboid", "banana"]\n')
    assert load_task(p).objects == ("mug", "cuboid", "banana")
    p.write_text('[task]\nname = "t"\nprotocol = "single_object"\n[objects]\nset = ["mug", "teapot"]\n')
    with pytest.raises(ConfigError) as e:
        load_task(p)
    msg = str(e.value)
    assert str(p) in msg and "'teapot'" in msg and "l_bracket" in msg and "\n" not in msg
