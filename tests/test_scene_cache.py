"""Settled trial scenes kept on disk: a run that restores them gives the records of one that simulates the
set-up, bit for bit, for spread single objects, piles, GIGA's piles and packed rounds; keys follow what the
set-up depends on; a damaged file is a miss."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from kgn_bench.bench.runner import read_trials, run_benchmark
from kgn_bench.bench.scene_cache import load_scene, scene_key
from kgn_bench.config import load_task

TASKS = Path(__file__).resolve().parents[1] / "tasks"


def _records(out: Path) -> list[dict]:
    rows = ({k: v for k, v in r.to_json().items() if k != "timing"} for r in read_trials(out / "trials.jsonl"))
    return sorted(rows, key=lambda r: r["index"])


def _task(name: str, trials: int):
    task = replace(load_task(TASKS / f"{name}.toml"), trials=trials)
    return replace(task, objects=("cuboid", "ring")) if task.spec.one_object else task


@pytest.mark.parametrize(("task_file", "trials"), [("ci_oracle", 1), ("ci_pile", 1), ("ci_giga_pile", 2),
                                                   ("giga_packed", 1)])
def test_a_run_from_kept_scenes_gives_the_same_records(task_file, trials, tmp_path, monkeypatch):
    task = _task(task_file, trials)
    monkeypatch.setenv("KGN_BENCH_SCENE_CACHE", "off")
    run_benchmark(task, "oracle", tmp_path / "plain", workers=1, progress=False)
    assert load_scene(task, 0) is None
    monkeypatch.setenv("KGN_BENCH_SCENE_CACHE", str(tmp_path / "cache"))
    run_benchmark(task, "oracle", tmp_path / "saving", workers=1, progress=False)
    assert all(load_scene(task, i) is not None for i in range(task.n_trials))
    run_benchmark(task, "oracle", tmp_path / "restoring", workers=1, progress=False)
    plain = _records(tmp_path / "plain")
    assert plain and any(r["attempts"] for r in plain)
    assert _records(tmp_path / "saving") == plain
    assert _records(tmp_path / "restoring") == plain


def test_keys_follow_the_set_up_and_a_damaged_file_is_a_miss(tmp_path, monkeypatch):
    monkeypatch.setenv("KGN_BENCH_SCENE_CACHE", str(tmp_path))
    task = _task("ci_oracle", 1)
    assert scene_key(task) == scene_key(replace(task))
    assert scene_key(replace(task, seed=task.seed + 1)) != scene_key(task)
    run_benchmark(task, "oracle", tmp_path / "run", workers=1, progress=False)
    assert load_scene(task, 0) is not None
    (path,) = tmp_path.glob("*/0.npz")
    path.write_bytes(b"not a scene")
    assert load_scene(task, 0) is None
    run_benchmark(task, "oracle", tmp_path / "again", workers=1, progress=False)  # the miss is written again
    assert load_scene(task, 0) is not None
    assert _records(tmp_path / "again") == _records(tmp_path / "run")


def test_a_restored_scene_is_the_simulated_one_bit_for_bit(tmp_path, monkeypatch):
    """The state after set-up, and after a second of physics from it, is the same to the last bit."""
    import numpy as np

    from kgn_bench.bench.trial import _build_scene

    task = _task("ci_giga_pile", 1)
    monkeypatch.setenv("KGN_BENCH_SCENE_CACHE", str(tmp_path))
    simulated, _, members = _build_scene(task, 0, None)
    restored, _, kept = _build_scene(task, 0, None)
    assert load_scene(task, 0) is not None and kept == members
    assert restored.retired.keys() == simulated.retired.keys()
    for scene in (simulated, restored):
        scene.step(500)
    for name in ("qpos", "qvel", "qacc_warmstart", "xpos", "mocap_pos"):
        assert np.array_equal(getattr(restored.data, name), getattr(simulated.data, name)), name


def test_the_key_follows_the_arm_model(monkeypatch, tmp_path):
    """Editing the arm's MJCF (a file, not a module) gives new keys: a set-up simulated with another arm is
    never restored."""
    from kgn_bench.bench import scene_cache

    task = _task("ci_oracle", 1)
    before = scene_key(task)
    arm = tmp_path / "arm7.xml"
    arm.write_text(scene_cache.arm_xml().read_text() + "<!-- edited -->\n")
    monkeypatch.setattr(scene_cache, "arm_xml", lambda: arm)
    scene_cache._code_sha256.cache_clear()
    try:
        assert scene_key(task) != before
    finally:
        monkeypatch.undo()
        scene_cache._code_sha256.cache_clear()
    assert scene_key(task) == before
