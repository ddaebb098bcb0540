"""VGN's dataset files: round trip, the manifest's counts and identity, refusal of damaged files, atomic writes."""

import json

import numpy as np
import pytest

from kgn_bench.data import vgn_format
from kgn_bench.data.format import DatasetError
from kgn_bench.data.vgn_format import (
    MANIFEST,
    finalize_dataset,
    list_scene_ids,
    read_manifest,
    read_scene,
    scene_path,
    write_scene,
)
from kgn_bench.errors import OutputError
from kgn_bench.tsdf import VoxelGrid

GRID = VoxelGrid(0.12, 16, 4.0)


def _scene(rng, n=7, positives=3):
    tsdf = rng.uniform(0, 1, (16, 16, 16)).astype(np.float32)
    voxels = rng.uniform(0, 15, (n, 3))
    quats = rng.normal(size=(n, 4))
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    widths = rng.uniform(1, 9, n)
    labels = np.array([1] * positives + [0] * (n - positives))
    return tsdf, voxels, quats, widths, labels


def test_round_trip(tmp_path, rng):
    arrays = _scene(rng)
    path = write_scene(tmp_path, 12, *arrays, meta={"objects": 3})
    assert path == tmp_path / "scenes" / "000012.npz" == scene_path(tmp_path, 12)
    got = read_scene(tmp_path, 12)
    assert got.scene_id == "000012" and len(got) == 7 and got.meta == {"objects": 3}
    for stored, given in zip((got.tsdf, got.voxels, got.quats, got.widths, got.labels), arrays, strict=True):
        np.testing.assert_allclose(stored, given, rtol=1e-6, atol=1e-6)
    assert got.tsdf.dtype == got.voxels.dtype == np.float32 and got.labels.dtype == np.uint8


def test_every_yaws_outcome_round_trips_and_must_fit_the_labels(tmp_path, rng):
    tsdf, voxels, quats, widths, labels = _scene(rng, 4, 2)
    holds = np.array([[1, 1, 0], [1, 0, 0], [0, 0, 0], [0, 0, 0]], bool)
    write_scene(tmp_path, 0, tsdf, voxels, quats, widths, labels, holds=holds)
    got = read_scene(tmp_path, 0)
    assert got.holds.dtype == bool
    np.testing.assert_array_equal(got.holds, holds)
    write_scene(tmp_path, 1, tsdf, voxels, quats, widths, labels)  # data without them still reads
    assert read_scene(tmp_path, 1).holds is None
    for bad, match in ((holds[:3], r"holds must be \(N, Y\)"), (holds * 2, "holds must be 0 or 1"),
                       (holds[:, ::-1], "column 0 equal to the labels"),
                       (np.array([[1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0]]), "no 1 on a negative")):
        with pytest.raises(ValueError, match=match):
            write_scene(tmp_path, 2, tsdf, voxels, quats, widths, labels, holds=bad)
    assert not scene_path(tmp_path, 2).exists()


def test_manifest_counts_and_identity(tmp_path, rng):
    write_scene(tmp_path, 0, *_scene(rng, 7, 3))
    write_scene(tmp_path, 1, *_scene(rng, 5, 0))
    write_scene(tmp_path, "extra_2", *_scene(rng, 0, 0))  # a scene without grasps
    m = finalize_dataset(tmp_path, GRID, {"scenario": "packed"})
    assert [s.id for s in m.scenes] == ["000000", "000001", "extra_2"] == list_scene_ids(tmp_path)
    assert (m.grasps, m.positives, m.scenes[1].negatives) == (12, 3, 5)
    assert m.grid == GRID and m.settings == {"scenario": "packed"} and len(m.sha256) == 64
    assert read_manifest(tmp_path) == m
    for entry in m.scenes:
        assert len(read_scene(tmp_path, entry)) == entry.grasps
    # another scene's content gives another identity
    write_scene(tmp_path, 1, *_scene(rng, 5, 1))
    assert finalize_dataset(tmp_path, GRID).sha256 != m.sha256


def test_manifest_sums_the_scenes_generation_times(tmp_path, rng):
    write_scene(tmp_path, 0, *_scene(rng), meta={"seconds": {"scene": 1.5, "view": 0.25, "label": 10.0}})
    write_scene(tmp_path, 1, *_scene(rng), meta={"seconds": {"scene": 2.0, "view": 0.25, "label": 6.0}})
    write_scene(tmp_path, 2, *_scene(rng))  # a scene that recorded no times adds none
    m = finalize_dataset(tmp_path, GRID)
    assert m.generation_seconds == pytest.approx(20.0) and read_manifest(tmp_path) == m
    # a manifest from before the field reads as unknown
    raw = json.loads((tmp_path / MANIFEST).read_text())
    del raw["generation_seconds"]
    (tmp_path / MANIFEST).write_text(json.dumps(raw))
    assert read_manifest(tmp_path).generation_seconds is None


def test_damaged_files_are_refused_with_one_line_naming_them(tmp_path, rng):
    write_scene(tmp_path, 0, *_scene(rng))
    write_scene(tmp_path, 1, *_scene(rng))
    m = finalize_dataset(tmp_path, GRID)
    path = scene_path(tmp_path, 1)
    raw = path.read_bytes()
    path.write_bytes(raw[: len(raw) // 2])  # truncated
    for target in (1, m.scenes[1]):
        with pytest.raises(DatasetError) as e:
            read_scene(tmp_path, target)
        assert str(path) in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(DatasetError, match="damaged scene file"):
        finalize_dataset(tmp_path, GRID)
    # a whole, valid file that is not the one the manifest lists
    write_scene(tmp_path, 1, *_scene(rng))
    with pytest.raises(DatasetError, match="SHA-256 differs from the manifest"):
        read_scene(tmp_path, m.scenes[1])
    path.unlink()
    with pytest.raises(DatasetError, match="missing"):
        read_scene(tmp_path, m.scenes[1])


def test_a_hand_edited_or_foreign_manifest_is_refused(tmp_path, rng):
    with pytest.raises(DatasetError, match="no VGN dataset here"):
        read_manifest(tmp_path)
    write_scene(tmp_path, 0, *_scene(rng))
    finalize_dataset(tmp_path, GRID)
    data = json.loads((tmp_path / MANIFEST).read_text())
    data["files"][0]["positives"] = 7
    (tmp_path / MANIFEST).write_text(json.dumps(data))
    with pytest.raises(DatasetError, match="does not match the manifest's sha256"):
        read_manifest(tmp_path)
    (tmp_path / MANIFEST).write_text("{")
    with pytest.raises(DatasetError, match="unreadable manifest"):
        read_manifest(tmp_path)
    (tmp_path / MANIFEST).write_text(json.dumps({"format": "something else"}))
    with pytest.raises(DatasetError, match="not a VGN dataset manifest"):
        read_manifest(tmp_path)


def test_a_grid_of_another_size_is_refused(tmp_path, rng):
    write_scene(tmp_path, 0, *_scene(rng))
    with pytest.raises(DatasetError, match="the dataset's is 40³"):
        finalize_dataset(tmp_path)


def test_inconsistent_arrays_are_a_callers_bug(tmp_path, rng):
    tsdf, voxels, quats, widths, labels = _scene(rng)
    for bad, match in (((tsdf, voxels[:3], quats, widths, labels), "must agree"),
                       ((tsdf, voxels, quats * 2, widths, labels), "unit quaternions"),
                       ((tsdf, voxels, quats, widths, labels + 1), "0 or 1"),
                       ((tsdf, voxels + 16, quats, widths, labels), "round into the grid"),
                       ((tsdf[:8], voxels, quats, widths, labels), r"\(R, R, R\)")):
        with pytest.raises(ValueError, match=match):
            write_scene(tmp_path, 0, *bad)
    with pytest.raises(ValueError, match="scene id"):
        write_scene(tmp_path, "../escape", *_scene(rng))
    assert not scene_path(tmp_path, 0).exists()


def test_writes_are_atomic(tmp_path, rng, monkeypatch):
    """A write that dies half-way leaves the previous file whole and no temporary file behind."""
    write_scene(tmp_path, 0, *_scene(rng, 7, 3))
    before = scene_path(tmp_path, 0).read_bytes()

    def dies_half_way(f, **arrays):
        f.write(b"PK\x03\x04 partial zip")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(vgn_format.np, "savez_compressed", dies_half_way)
    with pytest.raises(OutputError, match="disk full"):
        write_scene(tmp_path, 0, *_scene(rng, 4, 1))
    monkeypatch.undo()
    assert scene_path(tmp_path, 0).read_bytes() == before
    assert sorted(p.name for p in (tmp_path / "scenes").iterdir()) == ["000000.npz"]
    assert len(read_scene(tmp_path, 0)) == 7
