"""Where object folders are found, how tasks name imported objects and packaged sets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kgn_bench.config import ConfigError, load_task
from kgn_bench.shapes import is_known, known_names, sample_shape
from kgn_bench.shapes.library import (
    PYBULLET_EXTRAS,
    find_object,
    library_roots,
    list_objects,
    load_object,
    packaged,
    pybullet_numbers,
    set_names,
    shadowed,
)
from kgn_bench.shapes.mesh_object import MANIFEST, ObjectError


def test_imported_objects_are_found(object_library):
    assert find_object("test_block") == object_library / "test_block"
    assert "test_block" in list_objects() and "test_block" in known_names() and is_known("test_block")
    assert load_object("test_block") is load_object("test_block")  # cached per process
    assert sample_shape("test_block", None).name == "test_block"
    with pytest.raises(ObjectError, match="unknown object 'nope'"):
        load_object("nope")


def test_the_real_object_split():
    test, train = pybullet_numbers("test"), pybullet_numbers("train")
    assert len(test) == 40 and len(set(test)) == 40 and all(n % 10 == 0 for n in test)
    assert len(train) == 900 and not set(test) & set(train)
    assert test == sorted(test) and pybullet_numbers("test") == test  # seeded: the same every time
    names = set_names("pybullet_test")
    assert len(names) == 43 and names[-3:] == list(PYBULLET_EXTRAS)
    assert packaged("pb_120") and packaged("pb_duck") and not packaged("pb_12") and not packaged("mug")
    with pytest.raises(ObjectError, match="unknown object set"):
        set_names("ycb")


@pytest.fixture
def load_task_text(tmp_path):
    def load(text: str):
        path = tmp_path / "t.toml"
        path.write_text(text)
        return load_task(path)
    return load


def _task(objects: str) -> str:
    return f'[task]\nname = "t"\nprotocol = "single_object"\n[objects]\nset = {objects}\n'


def test_tasks_name_imported_objects_and_sets(object_library, load_task_text):
    assert load_task_text(_task('["test_block", "cuboid"]')).objects == ("test_block", "cuboid")
    assert len(load_task_text(_task('"pybullet_test"')).objects) == 43  # imported on first use by the runner
    with pytest.raises(ConfigError, match=r"unknown object .teapot.*objects add"):
        load_task_text(_task('["teapot"]'))
    with pytest.raises(ConfigError, match="unknown object set 'ycb'"):
        load_task_text(_task('"ycb"'))
    assert load_task_text(_task('"pybullet_train:5"')).objects == ("pb_001", "pb_002", "pb_003", "pb_004", "pb_005")


def test_the_first_objects_of_a_set():
    """``<set>:N`` is the first N of the set's fixed order; the train split never holds a test object."""
    train = set_names("pybullet_train")
    assert len(train) == 900 and set_names("pybullet_train:300") == train[:300]
    assert set_names("pybullet_test:43") == set_names("pybullet_test")
    assert not set(train) & set(set_names("pybullet_test"))
    for bad in ("pybullet_train:0", "pybullet_train:901", "pybullet_train:x", "pybullet_train:"):
        with pytest.raises(ObjectError, match="how many of the set's 900 objects"):
            set_names(bad)


def test_the_real_object_test_set_ships_imported(monkeypatch, tmp_path):
    monkeypatch.setenv("KGN_BENCH_OBJECTS", str(tmp_path / "empty"))
    bundled = library_roots()[1]
    names = set_names("pybullet_test")
    assert [find_object(n) for n in names] == [bundled / n for n in names]
    for name in ("pb_000", "pb_duck"):
        obj = load_object(name)
        assert obj.name == name and len(obj.verified_grasps) > 50
    assert not list(bundled.glob("*/preview.png"))  # drawn again by an import, not shipped


def test_an_import_of_a_bundled_object_remakes_its_files(monkeypatch, tmp_path):
    """`objects import-set` writes into the user's library even though the package holds the object, and
    what it writes is what ships (the stage times in the manifest aside)."""
    from kgn_bench.objects.pybullet_set import import_set

    user = tmp_path / "lib"
    monkeypatch.setenv("KGN_BENCH_OBJECTS", str(user))
    assert import_set(names=["pb_000"], progress=False) == {}
    made, shipped = user / "pb_000", library_roots()[1] / "pb_000"
    assert find_object("pb_000") == made
    files = sorted(p.relative_to(shipped) for p in shipped.rglob("*") if p.is_file())
    assert files and files == sorted(p.relative_to(made) for p in made.rglob("*") if p.is_file() and
                                     p.name != "preview.png")
    for rel in files:
        if rel.name == MANIFEST:
            a, b = (json.loads((root / rel).read_text()) for root in (made, shipped))
            a.pop("timing_s"), b.pop("timing_s")
            assert a == b
        else:
            assert (made / rel).read_bytes() == (shipped / rel).read_bytes(), rel
    assert shadowed(["pb_000", "pb_010", "cuboid"]) == {}  # the same content: nothing to warn about
    grasps = np.load(made / "grasps.npz")
    np.savez(made / "grasps.npz", poses=grasps["poses"][:-1], widths=grasps["widths"][:-1])
    assert shadowed(["pb_000", "pb_010"]) == {"pb_000": made}


def test_no_training_object_is_a_test_object_by_name_or_mesh(object_library, tmp_path, monkeypatch):
    """The train split shares no name and no mesh file (SHA-256) with the test set, and an imported copy of a
    test object under another name is caught by its source mesh's hash."""
    import hashlib
    import shutil

    from kgn_bench.objects.pybullet_set import set_items
    from kgn_bench.shapes.library import test_set_leaks

    def sha(p):
        return hashlib.sha256(p.read_bytes()).hexdigest()

    test_meshes = {sha(it.mesh) for it in set_items("test")}
    train = set_items("train")
    assert len(test_meshes) == 43 and not any(sha(it.mesh) in test_meshes for it in train)
    assert test_set_leaks(["cuboid", "pb_001", "test_block"]) == []
    assert test_set_leaks(["pb_000", "cuboid", "pb_teddy"]) == ["pb_000", "pb_teddy"]
    shutil.copytree(library_roots()[1] / "pb_010", object_library / "my_shape")  # pb_010 renamed
    try:
        assert test_set_leaks(["my_shape", "test_block"]) == ["my_shape"]
    finally:
        shutil.rmtree(object_library / "my_shape")
