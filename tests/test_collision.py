"""Collision labels checked against an independent test: surface samples of the neighbours' meshes."""

import numpy as np
import trimesh

from kgn_bench.geometry import invert_pose, make_pose
from kgn_bench.grasp import GraspSet
from kgn_bench.gripper import GRIPPER, PANDA_HAND
from kgn_bench.shapes import EVAL_DENSITY, TRAIN_DENSITY
from kgn_bench.shapes.primitives import Cuboid, Cylinder, Sphere
from kgn_bench.sim.collision import (
    body_collisions,
    gripper_hits_table,
    label_collisions,
    label_scene,
    proxy_hits_table,
)
from kgn_bench.sim.scene import Scene, SceneObject


def _points_in_proxy(pose, width, points, shrink):
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    local = local - GRIPPER.proxy_centre
    half = GRIPPER.proxy_half_extents(width) - shrink
    return np.all(np.abs(local) < half, axis=1)


def _scene():
    objects = [
        SceneObject(Cuboid((0.06, 0.05, 0.08)), (1, 0, 0), make_pose(t=[0.0, 0.0, 0.04])),
        SceneObject(Cylinder(0.04, 0.07), (0, 1, 0), make_pose(t=[0.11, 0.0, 0.035])),
        SceneObject(Sphere(0.03), (0, 0, 1), make_pose(t=[-0.02, 0.09, 0.03])),
    ]
    return Scene(objects)


def test_free_grasps_clear_table_and_neighbours_and_flags_are_real():
    scene = _scene()
    labels = label_scene(scene, EVAL_DENSITY)
    samples = []
    for obj in scene.objects:
        pts, _ = trimesh.sample.sample_surface_even(obj.shape.mesh(), 6000, seed=0)
        samples.append(pts @ obj.pose[:3, :3].T + obj.pose[:3, 3])
    neighbour_hits = 0
    for i, grasps in enumerate(labels):
        others = np.concatenate([p for j, p in enumerate(samples) if j != i])
        assert 0 < grasps.collides.sum() < len(grasps)
        for T, w, c in zip(grasps.poses, grasps.widths, grasps.collides):
            corners = GRIPPER.proxy_corners(T[None], np.array([w]))[0]
            if not c:
                assert corners[:, 2].min() >= 0.0
                # 1.5 mm margin: collision pieces are polygonal, the mesh is smooth
                assert not np.any(_points_in_proxy(T, w, others, shrink=1.5e-3))
            elif corners[:, 2].min() >= 0.0:
                neighbour_hits += 1
                assert np.any(_points_in_proxy(T, w, others, shrink=-1.5e-3))
    assert neighbour_hits > 10


def test_bottom_grasps_of_an_upright_tube_hit_the_table():
    tube = Cylinder(0.04, 0.07)
    scene = Scene([SceneObject(tube, (1, 1, 1), make_pose(t=[0, 0, 0.035]))])
    g = label_collisions(scene, 0, tube.grasps(TRAIN_DENSITY).transformed(scene.object_pose(0)))
    bottom = g.poses[:, 2, 0] > 0.99  # approaching upwards
    assert bottom.sum() == 11 and np.all(g.collides[bottom])
    top = g.poses[:, 2, 0] < -0.99
    assert not np.any(g.collides[top])  # the grasped tube itself is excluded


def test_the_whole_gripper_is_tested_against_the_table_without_a_scene():
    """``gripper_hits_table``: the proxy at the grasp, and the palm and wrist swept from the pre-grasp."""
    down = make_pose(np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]]), [0, 0, 0.03])  # approach −z, 3 cm up
    side = make_pose(np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]), [0, 0, 0.05])  # approach +x, closing −y
    low = side.copy()
    low[2, 3] = 0.02  # the palm (5 cm tall here) and the wrist dip under the table, the 2 cm proxy does not
    hits = gripper_hits_table(np.stack([down, side, low]), np.full(3, 0.02), back=0.10, depth=0.01)
    np.testing.assert_array_equal(hits, [False, False, True])
    assert not proxy_hits_table(low[None], np.array([0.02]))[0]  # only the body sees it


def test_table_test_is_strict_at_the_surface():
    # approach −z: the box lies above the fingertips; it touches z = 0 only at its front face
    T = make_pose(np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]]), [0, 0, 0.0])
    assert T[2, 0] == -1
    assert not proxy_hits_table(T[None], np.array([0.05]))[0]
    T[2, 3] = -1e-4
    assert proxy_hits_table(T[None], np.array([0.05]))[0]


def test_proxy_state_is_restored_after_labelling():
    scene = _scene()
    before = (scene.model.geom_contype.copy(), scene.model.geom_conaffinity.copy())
    label_scene(scene, TRAIN_DENSITY)
    np.testing.assert_array_equal(scene.model.geom_contype, before[0])
    np.testing.assert_array_equal(scene.model.geom_conaffinity, before[1])
    scene.forward()
    proxy_body = scene.model.geom_bodyid[scene.proxy_geom]
    assert scene.data.xpos[proxy_body][2] > 10  # parked far away
    assert invert_pose(scene.object_pose(0)).shape == (4, 4)


def test_body_collisions_see_the_palm_and_wrist_where_the_proxy_does_not():
    # a top-down grasp on a 4 cm box, closing along world y; neighbours 9 cm away along the closing axis:
    # outside the proxy (it reaches w/2 + 2 cm = 4 cm), inside the palm's span (±12 cm)
    down = np.stack([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], axis=1)
    grasp = make_pose(down, [0.0, 0.0, 0.03])[None]
    box = SceneObject(Cuboid((0.04, 0.04, 0.05)), (1, 0, 0), make_pose(t=[0.0, 0.0, 0.025]))

    def scene_with(height):
        post = SceneObject(Cylinder(0.015, height), (0, 1, 0), make_pose(t=[0.0, 0.09, height / 2]))
        return Scene([box, post])

    tall, short = scene_with(0.16), scene_with(0.06)  # the palm's bottom passes 3 + 7 = 10 cm above the table
    for scene in (tall, short):
        assert not label_collisions(scene, 0, GraspSet.unlabelled(grasp, np.array([0.04]))).collides[0]
    assert body_collisions(tall, grasp, back=0.10)[0]
    assert not body_collisions(short, grasp, back=0.10)[0]
    # the swept path counts: a post reaching only above the grasped height is hit on the way down
    assert body_collisions(scene_with(0.16), grasp, back=0.0)[0]
    # a horizontal approach 3 cm over the table drags the wrist (4.5 cm radius) through the table top
    side = make_pose(np.stack([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]], axis=1), [0.0, 0.0, 0.03])
    assert body_collisions(Scene([box]), side[None], back=0.10)[0]
    assert not body_collisions(Scene([box]), grasp, back=0.10)[0]


def test_the_fully_open_fingers_of_the_floating_hand_are_swept_where_asked():
    """The Panda hand (no wrist) on the 4 cm box, closing along y; a 1 cm post 4.8 cm from the grasp along the
    closing axis, 4 cm tall: below the palm, outside the 4 cm grasp's narrow finger path, but in the path of a
    finger opened to 8 cm (its inner face at 4 cm, 1.2 cm thick)."""
    down = np.stack([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], axis=1)
    grasp = make_pose(down, [0.0, 0.0, 0.03])[None]
    box = SceneObject(Cuboid((0.04, 0.04, 0.05)), (1, 0, 0), make_pose(t=[0.0, 0.0, 0.025]))
    post = SceneObject(Cylinder(0.005, 0.04), (0, 1, 0), make_pose(t=[0.0, 0.048, 0.02]))
    scene = Scene([box, post])
    assert not body_collisions(scene, grasp, back=0.05, gripper=PANDA_HAND)[0]
    assert body_collisions(scene, grasp, back=0.05, gripper=PANDA_HAND, fingers_open=0.08)[0]
    assert not body_collisions(Scene([box]), grasp, back=0.05, gripper=PANDA_HAND, fingers_open=0.08)[0]


def test_a_wide_proxy_sees_a_neighbour_at_its_far_end():
    # the proxy is compiled 10 cm wide; a 16 cm grasp's proxy is 20 cm wide (w/2 + 2 cm each side). A post
    # 8.5 cm from the grasp along the closing axis is inside only the part beyond the compiled size: MuJoCo's
    # midphase (the bounding boxes of bodies with several geoms, like this tube) must be told the new size
    # too, or the post is missed
    down = np.stack([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], axis=1)
    target = SceneObject(Cylinder(0.06, 0.05), (1, 0, 0), make_pose(t=[0.0, 0.0, 0.025]))
    post = SceneObject(Cylinder(0.012, 0.1), (0, 1, 0), make_pose(t=[0.0, 0.095, 0.05]))
    grasp = GraspSet.unlabelled(make_pose(down, [0.0, 0.0, 0.04])[None], np.array([0.16]))
    assert label_collisions(Scene([target, post]), 0, grasp).collides[0]
    assert not label_collisions(Scene([target]), 0, grasp).collides[0]
