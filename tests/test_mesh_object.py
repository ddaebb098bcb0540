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
    with pytest.raises(TypeError, match="loaded from its folder by name"):  # names resolve in shapes.library
        MeshObject.from_dims(shape.dims())


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


def _damaged_library(tmp_path, object_library, damage):
    """A library holding a copy of test_block, damaged by ``damage(folder)``."""
    lib = tmp_path / "lib"
    shutil.copytree(object_library / "test_block", lib / "test_block")
    damage(lib / "test_block")
    return lib


@pytest.mark.parametrize("damage, fragment", [
    (lambda f: (f / "grasps.npz").write_bytes((f / "grasps.npz").read_bytes()[:200]), "grasps.npz: its SHA-256"),
    (lambda f: (f / "collision" / "hull_00.ply").unlink(), "hulls, its manifest records"),
    (lambda f: (f / "visual.ply").write_bytes((f / "visual.ply").read_bytes() + b"\n"), "visual.ply: its SHA-256"),
])  # fmt: skip
def test_a_damaged_library_is_one_line_before_any_trial(damage, fragment, tmp_path, object_library, monkeypatch,
                                                        capsys):
    from kgn_bench.cli import main
    from kgn_bench.shapes.mesh_object import check_object

    lib = _damaged_library(tmp_path, object_library, damage)
    with pytest.raises(ObjectError, match=fragment.replace("(", r"\(")):
        check_object(lib / "test_block")
    monkeypatch.setenv("KGN_BENCH_OBJECTS", str(lib))
    task = tmp_path / "t.toml"
    task.write_text('[task]\nname = "b"\nprotocol = "single_object"\ntrials = 1\n[objects]\nset = ["test_block"]\n')
    out = tmp_path / "run"
    assert main(["run", str(task), "--detector", "oracle", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "test_block" in err and fragment in err
    assert not (out / "trials.jsonl").exists()  # not blamed on the detector as an outcome
    assert main(["objects", "list"]) == 0  # the broken entry is marked, the list goes on
    listed = capsys.readouterr()
    assert "test_block       BROKEN:" in listed.out and "1 imported object(s) are broken" in listed.err


def test_a_truncated_grasps_file_without_recorded_hashes_is_still_an_object_error(tmp_path, object_library):
    def damage(folder):
        manifest = json.loads((folder / "object.json").read_text())
        del manifest["files_sha256"]  # as imported before hashes were recorded
        (folder / "object.json").write_text(json.dumps(manifest))
        (folder / "grasps.npz").write_bytes((folder / "grasps.npz").read_bytes()[:200])

    lib = _damaged_library(tmp_path, object_library, damage)
    with pytest.raises(ObjectError, match=r"grasps.npz: unreadable grasps \(BadZipFile"):
        _ = MeshObject(lib / "test_block").verified_grasps
