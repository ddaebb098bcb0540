import mujoco
import numpy as np
import pytest

from kgn_bench.geometry import make_pose, matrix_from_quat_wxyz
from kgn_bench.shapes import PRIMITIVES
from kgn_bench.shapes.primitives import Cuboid, Stick
from kgn_bench.sim.scene import PhysicsError, Scene, SceneObject


def _six_objects(rng):
    return [SceneObject(cls.sample(rng), (0.5, 0.5, 0.5)) for cls in PRIMITIVES.values()]


def test_object_pose_is_the_body_pose():
    T = make_pose(matrix_from_quat_wxyz([0.9, 0.1, -0.3, 0.2]), [0.1, -0.05, 0.2])
    scene = Scene([SceneObject(Cuboid((0.05, 0.06, 0.07)), (1, 0, 0), T)])
    b = scene.body_ids[0]
    np.testing.assert_allclose(scene.object_pose(0), T, atol=1e-12)
    np.testing.assert_allclose(scene.data.xpos[b], T[:3, 3], atol=1e-12)
    np.testing.assert_allclose(scene.data.xmat[b].reshape(3, 3), T[:3, :3], atol=1e-12)
    assert np.array_equal(scene.object_position(0), scene.object_pose(0)[:3, 3])


def test_a_snapshot_restores_a_fresh_scene_to_the_last_bit(rng):
    """Retired objects included; a snapshot of another scene's size is refused."""
    objects = _six_objects(rng)
    scene = Scene(objects)
    scene.step(50)
    scene.retire_object(2)
    snap = scene.snapshot()
    scene.step(100)
    fresh = Scene(objects)
    fresh.restore(snap)
    assert fresh.retired.keys() == {2} and fresh.data.time == snap.state[0]
    fresh.step(100)
    assert np.array_equal(fresh.data.qpos, scene.data.qpos) and np.array_equal(fresh.data.qvel, scene.data.qvel)
    with pytest.raises(ValueError, match="does not fit"):
        Scene(objects[:2]).restore(snap)


def test_mass_and_physics_options():
    box = Cuboid((0.05, 0.06, 0.07))
    scene = Scene([SceneObject(box, (1, 0, 0), make_pose(t=[0, 0, 0.035]))])
    assert scene.model.body_mass[scene.body_ids[0]] == pytest.approx(box.mass())
    assert scene.model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    assert scene.model.opt.timestep == 0.002


def test_step_raises_on_divergence():
    scene = Scene([SceneObject(Stick(0.01, 0.05), (1, 0, 0), make_pose(t=[0, 0, 0.01]))])
    scene.data.qvel[:] = np.nan
    with pytest.raises(PhysicsError):
        scene.step(1)


def test_object_contacts_detects_interpenetration():
    a = SceneObject(Cuboid((0.05, 0.05, 0.05)), (1, 0, 0), make_pose(t=[0, 0, 0.025]))
    b = SceneObject(Cuboid((0.05, 0.05, 0.05)), (0, 1, 0), make_pose(t=[0.03, 0, 0.025]))
    scene = Scene([a, b])
    assert scene.object_contacts(1, np.array([0]))
    scene.set_object_pose(1, make_pose(t=[0.2, 0, 0.025]))
    assert not scene.object_contacts(1, np.array([0]))


def test_the_arena_grows_with_the_scene():
    from kgn_bench.sim.scene import ARENA_BASE_MB, ARENA_MB_PER_GEOM, arena_megabytes

    box = SceneObject(Cuboid((0.05, 0.05, 0.05)), (1, 0, 0), make_pose(t=[0, 0, 0.025]))
    assert arena_megabytes([]) == ARENA_BASE_MB
    assert arena_megabytes([box] * 10) == ARENA_BASE_MB + 10 * ARENA_MB_PER_GEOM
    assert Scene([box]).model.narena == round(arena_megabytes([box]) * 1024) * 1024


def test_a_mujoco_fatal_error_becomes_a_physics_error(monkeypatch, rng):
    import kgn_bench.sim.scene as scene_module

    monkeypatch.setattr(scene_module, "arena_megabytes", lambda objects: 0.02)  # 20 KB: the stack overflows
    with pytest.raises(PhysicsError, match=r"^MuJoCo stopped at t = 0\.000 s: mj_stackAlloc: out of memory"):
        Scene(_six_objects(rng))


def test_a_retired_object_makes_no_contacts_stays_put_and_leaves_the_others_alone():
    from kgn_bench.shapes.primitives import Ring

    ring = SceneObject(Ring(0.03, 0.01), (1, 0, 0), make_pose(t=[0, 0, 0.005]))
    box = SceneObject(Cuboid((0.05, 0.05, 0.05)), (0, 1, 0), make_pose(t=[0.2, 0, 0.025]))

    def contacts_of(scene, i):
        labels = scene.geom_label[scene.data.contact.geom[: scene.data.ncon]]
        return int(np.sum(np.any(labels == i + 1, axis=1)))

    scene = Scene([ring, box], extend=lambda root: root.worldbody.add(
        "geom", name="ground", type="plane", size=(1, 1, 0.1), contype=1, conaffinity=3))
    scene.step(50)
    assert contacts_of(scene, 0) >= 8  # 24 boxes lying on the ground
    box_before = scene.object_pose(1)
    scene.retire_object(0)
    parked = scene.object_pose(0)
    scene.step(200)
    assert contacts_of(scene, 0) == 0 and contacts_of(scene, 1) > 0
    np.testing.assert_allclose(scene.object_pose(0), parked, atol=1e-9)  # held at rest
    assert parked[2, 3] < -10.0  # below the table, beyond the camera's far plane (10 m)
    np.testing.assert_allclose(scene.object_pose(1)[:3, 3], box_before[:3, 3], atol=1e-3)
    assert 0 not in scene.geom_label[scene.collision_geoms] - 1  # the gripper proxy no longer sees it
