"""An object folder read back as a Shape: geoms, grasps, mass, rest poses, and broken folders."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from kgn_bench.shapes import EVAL_DENSITY, TRAIN_DENSITY, GraspDensity, shape_from_dims
from kgn_bench.shapes.mesh_object import MeshObject, ObjectError


def test_block_as_a_shape(object_library):
    shape = MeshObject(object_library / "test_block")
    assert shape.name == "test_block" and shape.dims() == {"object": "test_block"}
    geoms = shape.collision_geoms()
    assert all(g.kind == "mesh" for g in geoms) and 1 <= len(geoms) <= 2
    inside = shape.contains(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.049], [0.0, 0.0, 0.06]]))
    assert inside.tolist() == [True, True, False]
    assert shape.mass() == pytest.approx(0.168) and shape.volume() == pytest.approx(0.04 * 0.06 * 0.10)
    assert all(np.allclose(p.R @ p.R.T, np.eye(3), atol=1e-6) for p in shape.rest_poses())
    assert shape_from_dims("test_block", shape.dims()).folder == shape.folder


def test_grasp_density_subsamples_the_verified_grasps(object_library):
    shape = MeshObject(object_library / "test_block")
    every = shape.verified_grasps
    assert len(shape.grasps(EVAL_DENSITY)) == min(len(every), 10 * 30 * 4)
    few = shape.grasps(GraspDensity(translations=1, angles=2))
    assert len(few) == min(len(every), 8)
    assert all(any(np.allclose(p, q) for q in every.poses) for p in few.poses)
    assert len(shape.grasps(TRAIN_DENSITY)) <= len(shape.grasps(EVAL_DENSITY))


def test_broken_folders(tmp_path, object_library):
    bad = tmp_path / "broken"
    shutil.copytree(object_library / "test_block", bad)
    m = json.loads((bad / "object.json").read_text())
    (bad / "object.json").write_text(json.dumps({**m, "version": 99}))
    with pytest.raises(ObjectError, match="manifest version 99"):
        MeshObject(bad)
    (bad / "object.json").write_text("{not json")
    with pytest.raises(ObjectError, match="unreadable manifest"):
        MeshObject(bad)
    (bad / "object.json").write_text(json.dumps(m))
    for hull in (bad / "collision").glob("*.ply"):
        hull.unlink()
    with pytest.raises(ObjectError, match="no collision hulls"):
        MeshObject(bad).collision_geoms()
    (bad / "grasps.npz").write_bytes(b"garbage")
    with pytest.raises(ObjectError, match="unreadable grasps"):
        _ = MeshObject(bad).verified_grasps
    with pytest.raises(ObjectError, match="not an object folder"):
        MeshObject(tmp_path)
