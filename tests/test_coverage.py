"""Rest-pose coverage: which grasps the gripper can execute on an object resting on the table, and a
verification budget that gives every rest pose some."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from kgn_bench.geometry import make_pose
from kgn_bench.objects.coverage import REST_GRASPS, coverage_subset, executable, rest_pose_grasps, rest_transforms
from kgn_bench.shapes.mesh_object import MeshObject

FLAT = np.eye(3).tolist()
ON_SIDE = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]  # R_x(90°): the object's +y points up


def _grasp(approach, closing, centre=(0.0, 0.0, 0.0)):
    """``T_obj_grasp`` approaching along ``approach`` and closing along ``closing`` (object frame)."""
    x, z = np.asarray(approach, float), np.asarray(closing, float)
    return make_pose(np.column_stack([x, np.cross(z, x), z]), centre)


def test_rest_transforms_put_the_lowest_point_on_the_table():
    box = trimesh.creation.box((0.04, 0.06, 0.10))
    T = rest_transforms(box, [FLAT, ON_SIDE])
    for Tk in T:
        z = (box.vertices @ Tk[:3, :3].T + Tk[:3, 3])[:, 2]
        assert z.min() == pytest.approx(0.0)
    assert T[0, 2, 3] == pytest.approx(0.05) and T[1, 2, 3] == pytest.approx(0.03)


def test_a_top_down_grasp_is_executable_only_in_the_pose_that_puts_its_approach_down():
    box = trimesh.creation.box((0.04, 0.06, 0.10))
    down_z = _grasp([0, 0, -1], [1, 0, 0], (0, 0, 0.03))  # from above when the box stands on its end
    down_y = _grasp([0, -1, 0], [1, 0, 0], (0, 0.01, -0.04))  # from above on its side (+y up); standing, 1 cm up
    up_z = _grasp([0, 0, 1], [1, 0, 0], (0, 0, -0.03))  # from below when it stands
    ok = executable(box, [FLAT, ON_SIDE], np.stack([down_z, down_y, up_z]), np.full(3, 0.04))
    np.testing.assert_array_equal(ok, [[True, False, False], [False, True, False]])


def test_the_subset_gives_every_rest_pose_its_share_before_the_rest():
    rng = np.random.default_rng(0)
    n = 400
    poses = np.stack([_grasp(a / np.linalg.norm(a), [0, 0, 1] if abs(a[2]) < 0.9 else [1, 0, 0])
                      for a in rng.normal(size=(n, 3))])
    ok = np.zeros((2, n), dtype=bool)
    ok[0, :300] = True  # the likely pose: most candidates work there
    ok[1, 395:] = True  # the other: 5 candidates
    pick = coverage_subset(ok, poses, 40, rng)
    assert len(pick) == 40 and np.all(np.diff(pick) > 0)
    assert ok[1, pick].sum() == 5 and ok[0, pick].sum() >= REST_GRASPS
    again = coverage_subset(ok[1:], poses, 10, rng, exclude=np.isin(np.arange(n), pick))
    assert not np.isin(again, pick).any() and len(again) == 10


def test_imported_objects_count_their_grasps_per_rest_pose(object_library):
    shape = MeshObject(object_library / "test_block")
    counts = rest_pose_grasps(shape)
    assert len(counts) == len(shape.manifest["rest_poses"]) and all(n >= 1 for _, n in counts)
    assert sum(p for p, _ in counts) == pytest.approx(1.0)
    # an object imported before the counts existed gets them counted from its grasps, the same numbers
    for rest in shape.manifest["rest_poses"]:
        rest.pop("grasps")
    assert rest_pose_grasps(shape) == counts
