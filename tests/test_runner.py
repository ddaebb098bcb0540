"""The benchmark runner end to end on real trials: output files, resume after a kill, worker-count independence,
refusal of a foreign run folder, a clearance scene, and `kgn-bench run`."""

import json
import os
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

from kgn_bench.bench.records import TrialRecord
from kgn_bench.bench.runner import RunError, read_trials, run_benchmark
from kgn_bench.bench.stats import summarise, summary_markdown
from kgn_bench.bench.trial import TIMING_KEYS
from kgn_bench.cli import main
from kgn_bench.config import load_task
from kgn_bench.errors import InputError

TASKS = Path(__file__).resolve().parents[1] / "tasks"


@pytest.fixture(scope="module")
def task():
    """ci_oracle with two objects: two single-object trials (indices 0 = cuboid, 1 = sphere)."""
    return replace(load_task(TASKS / "ci_oracle.toml"), objects=("cuboid", "sphere"))


@pytest.fixture(scope="module")
def first_run(task, tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "base"
    result = run_benchmark(task, "oracle", out, workers=1, progress=False)
    return out, result


def _records(out):
    return sorted(
        ({k: v for k, v in r.to_json().items() if k != "timing"} for r in read_trials(out / "trials.jsonl")),
        key=lambda r: r["index"],
    )


def _copy(src, tmp_path):
    dst = tmp_path / "copy"
    shutil.copytree(src, dst)
    return dst


def test_run_writes_trials_and_summaries(task, first_run):
    out, result = first_run
    assert result.ran == 2
    for name in ("run.json", "trials.jsonl", "summary.json", "summary.md", "timing.json"):
        assert (out / name).is_file(), name
    lines = (out / "trials.jsonl").read_text().splitlines()
    assert len(lines) == 2
    records = [json.loads(line) for line in lines]
    assert sorted(r["index"] for r in records) == [0, 1]
    by_index = {r["index"]: r for r in records}
    assert by_index[0]["objects"] == ["cuboid"] and by_index[1]["objects"] == ["sphere"]
    for r in records:
        assert r["protocol"] == "single_object" and r["placed"] == 1
        assert len(r["attempts"]) == 1  # single_object: one attempt
        a = r["attempts"][0]
        assert a["candidates"] > 0 and a["selected"] is not None  # the oracle always offers a reachable grasp
        assert r["removed"] == int(a["success"])
        assert set(r["timing"]) == set(TIMING_KEYS)
    summary = json.loads((out / "summary.json").read_text())
    assert summary == result.summary
    assert {k: summary[k] for k in ("task", "protocol", "detector", "seed")} == {
        "task": "ci_oracle", "protocol": "single_object", "detector": "oracle", "seed": 0}  # fmt: skip
    assert summary["trials"] == 2 and summary["attempts"] == 2
    assert summary == summarise([TrialRecord.from_json(r) for r in records],
                                {k: summary[k] for k in ("task", "protocol", "detector", "seed")})
    assert summary["rates"]["success"]["k"] >= 1  # the oracle picks up at least one of a box and a ball
    assert set(summary["per_object"]) == {"cuboid", "sphere"}
    assert (out / "summary.md").read_text() == summary_markdown(summary)
    timing = json.loads((out / "timing.json").read_text())
    assert timing["trials_run"] == 2 and timing["workers"] == 1 and timing["wall_s"] > 0
    assert set(timing["per_trial_s"]) == set(TIMING_KEYS) and timing["simulated_s_per_trial"] > 0
    run = json.loads((out / "run.json").read_text())
    assert run["trials"] == task.n_trials == 2 and run["seed"] == 0 and run["detector"] == "oracle"


def test_rerun_resumes_without_duplicating(first_run, task, tmp_path):
    out = _copy(first_run[0], tmp_path)
    before = (out / "trials.jsonl").read_text()
    timing = (out / "timing.json").read_text()
    result = run_benchmark(task, "oracle", out, workers=1, progress=False)
    assert result.ran == 0
    assert (out / "trials.jsonl").read_text() == before
    assert (out / "timing.json").read_text() == timing  # the figures of the run that did the work stay
    assert result.timing == json.loads(timing)
    assert result.summary == first_run[1].summary
    assert json.loads((out / "summary.json").read_text()) == first_run[1].summary


def test_a_run_resumes_under_other_resource_reservations(first_run, task, tmp_path):
    from kgn_bench.config import ResourceConfig

    out = _copy(first_run[0], tmp_path)
    reserving = replace(task, resources=ResourceConfig(num_cpus=2.0, num_gpus=0.5))
    result = run_benchmark(reserving, "oracle", out, workers=1, progress=False)  # not "another run"
    assert result.ran == 0 and result.summary == first_run[1].summary


def test_a_trial_cut_short_by_a_kill_is_rerun(first_run, task, tmp_path):
    out = _copy(first_run[0], tmp_path)
    lines = (out / "trials.jsonl").read_text().splitlines(keepends=True)
    killed_index = json.loads(lines[-1])["index"]
    (out / "trials.jsonl").write_text(lines[0] + lines[1][: len(lines[1]) // 2])  # killed mid-write
    for name in ("summary.json", "summary.md", "timing.json"):
        (out / name).unlink()
    result = run_benchmark(task, "oracle", out, workers=1, progress=False)
    assert result.ran == 1
    records = read_trials(out / "trials.jsonl")
    assert [r.index for r in records] == [json.loads(lines[0])["index"], killed_index]
    assert (out / "summary.json").read_text() == (first_run[0] / "summary.json").read_text()
    assert _records(out) == _records(first_run[0])


def test_read_trials_drops_a_cut_short_last_line(first_run, tmp_path):
    path = tmp_path / "trials.jsonl"
    lines = (first_run[0] / "trials.jsonl").read_text().splitlines(keepends=True)
    path.write_text(lines[0] + lines[1][:40])
    records = read_trials(path)
    assert [r.index for r in records] == [json.loads(lines[0])["index"]]
    assert path.read_text() == lines[0]  # the partial line is removed from the file
    # a complete last line without its newline is also treated as cut short (it may be incomplete JSON)
    path.write_text(lines[0] + lines[1].rstrip("\n"))
    assert len(read_trials(path)) == 1 and path.read_text() == lines[0]
    # a duplicate (a trial finished twice) counts once; a bad line in the middle is corruption
    path.write_text(lines[0] + lines[1] + lines[0])
    assert sorted(r.index for r in read_trials(path)) == [0, 1]
    path.write_text(lines[0] + "{oops\n" + lines[1])
    with pytest.raises(RunError, match="line 2"):
        read_trials(path)
    assert read_trials(tmp_path / "missing.jsonl") == []


def test_two_workers_give_the_same_results(first_run, task, tmp_path):
    out = tmp_path / "w2"
    result = run_benchmark(task, "oracle", out, workers=2, progress=False)
    assert result.ran == 2 and result.timing["workers"] == 2
    assert (out / "summary.json").read_text() == (first_run[0] / "summary.json").read_text()
    assert _records(out) == _records(first_run[0])


def test_a_folder_holding_another_run_is_refused(first_run, task, tmp_path):
    out = _copy(first_run[0], tmp_path)
    before = (out / "trials.jsonl").read_text()
    with pytest.raises(RunError, match=r"holds another run \(different .*seed"):
        run_benchmark(task.with_overrides(seed=1), "oracle", out, progress=False)
    with pytest.raises(RunError, match="detector"):
        run_benchmark(task, "random", out, progress=False)
    assert (out / "trials.jsonl").read_text() == before  # nothing touched
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "notes.txt").write_text("mine")
    with pytest.raises(RunError, match="not empty"):
        run_benchmark(task, "oracle", junk, progress=False)
    (out / "run.json").write_text("{")
    with pytest.raises(RunError, match="corrupt"):
        run_benchmark(task, "oracle", out, progress=False)


def test_bad_arguments(task, tmp_path):
    with pytest.raises(InputError, match="unknown detector 'nope'"):
        run_benchmark(task, "nope", tmp_path / "a", progress=False)
    with pytest.raises(ValueError, match="workers"):
        run_benchmark(task, "oracle", tmp_path / "b", workers=0, progress=False)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_clearance_scene(tmp_path):
    task = replace(load_task(TASKS / "multi_object.toml"), objects_per_scene=2, trials=1)
    result = run_benchmark(task, "oracle", tmp_path / "multi", progress=False)
    (record,) = read_trials(tmp_path / "multi" / "trials.jsonl")
    assert record.protocol == "multi_object" and len(record.objects) == 2
    assert set(record.objects) <= set(task.objects)
    assert record.placed == 2 and sorted(record.placed_objects) == sorted(record.objects)
    assert record.fell_at_setup is None and "fallen" not in record.to_json()  # not a clutter round
    attempts = record.attempts
    assert 1 <= len(attempts) <= task.execution.max_attempts_per_object * 2
    assert record.removed == record.successes <= 2
    picked = [a.object for a in attempts if a.success]
    assert len(set(picked)) == len(picked)  # an object removed is not picked again
    # it stops when the table is clear or after max_consecutive_failures failures in a row
    failures_at_end = len(attempts) - max([i + 1 for i, a in enumerate(attempts) if a.success], default=0)
    assert record.removed == 2 or failures_at_end == task.execution.max_consecutive_failures
    rates = result.summary["rates"]
    assert rates["clear"]["n"] == 2 and rates["clear"]["k"] == record.removed
    assert rates["success"]["n"] == len(attempts) and rates["scenes_cleared"]["n"] == 1


def _small_task(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text('[task]\nname = "tiny"\nprotocol = "single_object"\ntrials = 3\n[objects]\nset = ["cuboid"]\n')
    return p


def test_cli_run(tmp_path, capsys):
    out = tmp_path / "run"
    argv = ["run", str(_small_task(tmp_path)), "--detector", "oracle", "--trials", "1", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("# tiny: oracle (single_object, seed 0)")
    assert "| success |" in printed and "1 trials in" in printed and f"wrote {out}/summary.json" in printed
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"] == 1 and summary["per_object"].keys() == {"cuboid"}  # --trials overrode 3


def test_cli_run_errors(tmp_path, capsys):
    task = _small_task(tmp_path)
    out = tmp_path / "run"
    assert main(["run", str(task), "--detector", "nope", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("kgn-bench: error:") and "unknown detector 'nope'" in err and err.count("\n") == 1
    bad = tmp_path / "bad.toml"
    bad.write_text("[task]\nname = 'x'\nprotocol = 'single_object'\ntrials = 'many'\n")
    assert main(["run", str(bad), "--detector", "oracle", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "trials must be int" in err
    assert main(["run", str(tmp_path / "none.toml"), "--detector", "oracle", "--quiet"]) == 2
    assert "no such task file" in capsys.readouterr().err
    assert not out.exists()


def test_learned_detector_weights_are_checked_and_part_of_the_identity(tmp_path, monkeypatch, small_model):
    import kgn_bench.detectors.kgn as kgn
    from kgn_bench.bench.runner import run_identity
    from kgn_bench.model.checkpoint import CheckpointError

    monkeypatch.setattr(kgn, "WEIGHTS_DIR", tmp_path / "weights")
    task = load_task(TASKS / "ci_oracle.toml")
    with pytest.raises(CheckpointError, match="no checkpoint at"):
        run_benchmark(task, "kgnv2", tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()  # nothing written before the weights were found
    hashes = []
    for seed in (0, 1):
        small_model(tmp_path / "weights" / "kgnv2.pt", seed=seed)
        hashes.append(run_identity(task, "kgnv2")["weights_sha256"])
    assert len(hashes[0]) == 64
    assert hashes[0] != hashes[1]  # other weights: another run, never resumed into the same folder
    assert "weights_sha256" not in run_identity(task, "oracle")


BAD_DETECTORS = '''
import numpy as np
from kgn_bench.detectors.antipodal import AntipodalDetector


class ReturnsNone(AntipodalDetector):
    name = "returns_none"

    def detect(self, observation):
        return None


class ResetRaises(AntipodalDetector):
    name = "reset_raises"

    def reset(self, seed):
        raise RuntimeError("no seed for me")


class Stretched(AntipodalDetector):
    name = "stretched"

    def detect(self, observation):
        cands = super().detect(observation)
        poses = cands.poses.copy()
        poses[:, :3, :3] *= 3.0
        return type(cands)(poses, cands.widths, cands.confidences, cands.reprojection_errors)


class BadConstructor:
    def __init__(self):
        raise OSError("weights server unreachable")
'''


@pytest.fixture
def bad_detectors(tmp_path, monkeypatch):
    """A module of faulty detectors, importable here and in spawned workers."""
    import sys

    folder = tmp_path / "mods"
    folder.mkdir()
    (folder / "baddets.py").write_text(BAD_DETECTORS)
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.setenv("PYTHONPATH", str(folder) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    yield "baddets"
    sys.modules.pop("baddets", None)


@pytest.mark.parametrize("name, reason, detail", [
    ("ReturnsNone", "detector_error", "detect returned NoneType, not Candidates"),
    ("ResetRaises", "detector_error", "reset: RuntimeError: no seed for me"),
    ("Stretched", "no_candidate", ""),
])
def test_a_faulty_detector_becomes_attempts_and_the_run_goes_on(tmp_path, bad_detectors, name, reason, detail):
    task = replace(load_task(_small_task(tmp_path)), trials=2)
    result = run_benchmark(task, f"{bad_detectors}:{name}", tmp_path / name, progress=False)
    records = read_trials(tmp_path / name / "trials.jsonl")
    failures = {k: v for k, v in result.summary["failures"].items() if v}
    assert len(records) == 2 and failures == {reason: 2}
    assert all(r.attempts[0].detail.endswith(detail) for r in records)
    if name == "Stretched":  # never executed: every candidate is counted as an invalid pose
        assert all(r.attempts[0].rejected["invalid_pose"] == r.attempts[0].candidates > 0 for r in records)


def test_a_detector_that_cannot_be_built_stops_the_run_before_anything_is_written(tmp_path, bad_detectors, capsys):
    out = tmp_path / "run"
    argv = ["run", str(_small_task(tmp_path)), "--detector", f"{bad_detectors}:BadConstructor", "--workers", "2",
            "--out", str(out), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err == (f"kgn-bench: error: detector '{bad_detectors}:BadConstructor' could not be built: "
                   "OSError: weights server unreachable\n")
    assert not out.exists()


def test_a_physics_fault_is_the_trials_physics_error_and_the_run_goes_on(tmp_path, monkeypatch):
    import kgn_bench.sim.scene as scene_module

    real = scene_module.arena_megabytes
    # trial 1's scene gets a 20 KB arena: MuJoCo's stack overflows (mujoco.FatalError) while it is built
    monkeypatch.setattr(scene_module, "arena_megabytes",
                        lambda objects: 0.02 if objects and objects[0].shape.name == "cylinder" else real(objects))
    p = tmp_path / "two.toml"
    p.write_text('[task]\nname = "two"\nprotocol = "single_object"\ntrials = 1\n'
                 '[objects]\nset = ["cuboid", "cylinder", "sphere"]\n')
    result = run_benchmark(load_task(p), "oracle", tmp_path / "run", progress=False)
    records = sorted(read_trials(tmp_path / "run" / "trials.jsonl"), key=lambda r: r.index)
    assert [r.attempts[0].reason for r in records] == [None, "physics_error", None]
    assert records[1].attempts[0].detail.startswith("no stable scene: MuJoCo stopped at t = 0.000 s: "
                                                          "mj_stackAlloc: out of memory")
    assert {k: v for k, v in result.summary["failures"].items() if v} == {"physics_error": 1}


def test_a_lock_planted_as_a_symbolic_link_is_refused_and_its_target_kept(tmp_path, capsys):
    out, target = tmp_path / "run", tmp_path / "precious"
    out.mkdir()
    target.write_text("keep me")
    (out / ".lock").symlink_to(target)
    argv = ["run", str(_small_task(tmp_path)), "--detector", "oracle", "--trials", "1", "--out", str(out), "--quiet"]
    assert main(argv) == 2
    assert "is a symbolic link" in capsys.readouterr().err
    assert target.read_text() == "keep me"


def test_a_second_run_into_a_folder_in_use_is_refused(tmp_path, capsys):
    from kgn_bench.bench.runner import run_lock

    out = tmp_path / "run"
    argv = ["run", str(_small_task(tmp_path)), "--detector", "oracle", "--trials", "1", "--out", str(out), "--quiet"]
    with run_lock(out):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err == f"kgn-bench: error: {out} is being written by another run (pid {os.getpid()}); wait for it " \
                      "or use another --out\n"
        assert sorted(p.name for p in out.iterdir()) == [".lock"]
    assert main(argv) == 0  # released: the folder is usable
    assert len(read_trials(out / "trials.jsonl")) == 1


def test_run_json_records_the_environment(tmp_path):
    from kgn_bench.environment import environment

    run_benchmark(replace(load_task(_small_task(tmp_path)), trials=1), "oracle", tmp_path / "r", progress=False)
    assert json.loads((tmp_path / "r" / "run.json").read_text())["environment"] == environment()


def test_learned_detector_trials_are_identical_whatever_the_worker_count(tmp_path):
    p = tmp_path / "k.toml"
    p.write_text('[task]\nname = "k"\nprotocol = "single_object"\ntrials = 2\n'
                 '[objects]\nset = ["cuboid", "ring", "stick"]\n')
    task = load_task(p)
    records = {}
    for workers in (1, 2):
        run_benchmark(task, "kgnv2", tmp_path / f"w{workers}", workers=workers, progress=False)
        records[workers] = sorted(({k: v for k, v in r.to_json().items() if k != "timing"}
                                   for r in read_trials(tmp_path / f"w{workers}" / "trials.jsonl")),
                                  key=lambda r: r["index"])
    assert len(records[1]) == 6 and records[1] == records[2]
    assert (tmp_path / "w1" / "summary.json").read_text() == (tmp_path / "w2" / "summary.json").read_text()


def test_the_tasks_execution_settings_reach_the_detectors(tmp_path):
    """--set execution.pregrasp_distance=0.15 changes the antipodal clearance sweep and the oracle's body check."""
    from kgn_bench.bench.trial import run_trial
    from kgn_bench.config import apply_override
    from kgn_bench.detectors import make_detector
    from kgn_bench.sim.control import IK

    task = apply_override(replace(load_task(_small_task(tmp_path)), trials=1), "execution.pregrasp_distance", "0.15")
    ik = IK()
    for name in ("antipodal", "oracle"):
        detector = make_detector(name)
        run_trial(task, 0, detector, ik)
        assert getattr(detector, "pregrasp_distance", getattr(detector, "approach", None)) == 0.15, name


@pytest.fixture
def tiny_disk(tmp_path):
    """A 64 KB tmpfs with 8 KB free (skipped where mounting is not allowed)."""
    import subprocess

    mount = tmp_path / "disk"
    mount.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    (mount / "pad").write_bytes(b"\0" * 56 * 1024)
    yield mount
    subprocess.run(["umount", str(mount)], check=True)


def test_a_full_disk_is_one_line_naming_the_file(tiny_disk, tmp_path, capsys):
    out = tiny_disk / "run"
    argv = ["run", str(_small_task(tmp_path)), "--detector", "oracle", "--trials", "2", "--out", str(out), "--quiet"]
    assert main(argv) == 2
    assert capsys.readouterr().err == f"kgn-bench: error: cannot write {out}/trials.jsonl: disk full\n"
    assert read_trials(out / "trials.jsonl") == [] or len(read_trials(out / "trials.jsonl")) < 2  # nothing corrupt


@pytest.mark.parametrize("protocol", ["pile", "packed"])
def test_clutter_rounds_end_as_published_and_count_what_fell(tmp_path, protocol):
    """A pile or packed round with the oracle: objects on the table at the start, attempts until the table is
    clear, 2 failures in a row or one attempt with nothing to execute; the record counts what fell."""
    task = replace(load_task(protocol), objects_per_scene=3, trials=2)
    result = run_benchmark(task, "oracle", tmp_path / protocol, progress=False)
    for record in read_trials(tmp_path / protocol / "trials.jsonl"):
        assert record.protocol == protocol and len(record.objects) == 3
        assert record.placed + record.fell_at_setup == 3
        attempts = record.attempts
        reasons = [a.reason for a in attempts]
        assert all(r not in ("no_candidate", "unreachable") for r in reasons[:-1])  # those end the round
        tail = len(attempts) - max([i + 1 for i, a in enumerate(attempts) if a.success], default=0)
        ended = (record.removed == record.placed or tail == 2 or reasons[-1] in ("no_candidate", "unreachable")
                 or len(attempts) == task.execution.max_attempts_per_object * 3)
        assert ended and record.removed + record.fallen <= record.placed
    summary = result.summary
    assert {"success", "clear", "scenes_cleared"} <= set(summary["rates"]) and "fallen" in summary


def test_removing_placed_objects_is_part_of_a_rounds_identity_only(task):
    from kgn_bench.bench.runner import run_identity

    multi = replace(load_task(TASKS / "multi_object.toml"), trials=1)
    kept = replace(multi, execution=replace(multi.execution, remove_placed=False))
    assert multi.execution.remove_placed
    assert run_identity(multi, "oracle") != run_identity(kept, "oracle")  # a round's outcome may change
    single = replace(task, execution=replace(task.execution, remove_placed=False))
    assert run_identity(task, "oracle") == run_identity(single, "oracle")  # one attempt: nothing to remove
    assert "remove_placed" not in run_identity(task, "oracle")["config"]["execution"]


def test_camera_settings_added_later_enter_the_identity_only_when_set(task):
    """Runs recorded before ``noise_model`` and ``intrinsics`` existed keep their identity at the defaults."""
    from kgn_bench.bench.runner import run_identity

    camera = run_identity(task, "oracle")["config"]["camera"]
    assert "noise_model" not in camera and "intrinsics" not in camera
    giga = replace(task, camera=replace(task.camera, intrinsics="giga", noise_model="dex", depth_noise=1.0))
    camera = run_identity(giga, "oracle")["config"]["camera"]
    assert camera["intrinsics"] == "giga" and camera["noise_model"] == "dex"


def test_a_task_can_name_gigas_camera(tmp_path):
    """A trial with ``[camera] intrinsics = "giga"`` renders and detects with the 540 px camera."""
    from kgn_bench.camera import GIGA
    from kgn_bench.detectors.oracle import OracleDetector

    base = load_task(TASKS / "single_object.toml")
    task = replace(base, objects=("cuboid",), trials=1,
                   camera=replace(base.camera, intrinsics="giga", noise_model="dex", depth_noise=1.0))
    seen = []
    real = OracleDetector.detect
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(OracleDetector, "detect", lambda self, obs: (seen.append(obs), real(self, obs))[1])
        run_benchmark(task, "oracle", tmp_path / "giga", workers=1, progress=False)
    assert seen and seen[0].intrinsics == GIGA and seen[0].depth.shape == (480, 640)


@pytest.mark.parametrize("remove", [True, False])
def test_a_round_removes_each_object_it_puts_in_the_bin_when_asked(tmp_path, monkeypatch, remove):
    from kgn_bench.sim.scene import Scene

    retired = []
    real = Scene.retire_object
    monkeypatch.setattr(Scene, "retire_object", lambda self, i: (retired.append(i), real(self, i)))
    base = load_task(TASKS / "pile.toml")
    task = replace(base, objects_per_scene=3, trials=1, execution=replace(base.execution, remove_placed=remove))
    run_benchmark(task, "oracle", tmp_path / "pile", progress=False)
    (record,) = read_trials(tmp_path / "pile" / "trials.jsonl")
    picked = [record.objects.index(a.object) for a in record.attempts if a.success]
    assert record.removed >= 1 and record.fallen == 0  # removed objects are not counted as fallen
    assert retired == (picked if remove else [])


def test_runs_on_one_shared_pool_give_the_same_files_as_one_after_another(tmp_path):
    from kgn_bench.bench.runner import run_many

    single = replace(load_task(TASKS / "ci_oracle.toml"), objects=("cuboid", "sphere", "stick"))
    multi = replace(load_task(TASKS / "multi_object.toml"), name="multi_small", objects_per_scene=2, trials=2)
    specs = [(t, d) for t in (single, multi) for d in ("oracle", "antipodal")]
    for task, det in specs:
        run_benchmark(task, det, tmp_path / "seq" / task.name / det, workers=1, progress=False)
    # a kill left the second run of the pool half done: the shared pool resumes it with the others
    half = tmp_path / "pool" / single.name / "antipodal"
    shutil.copytree(tmp_path / "seq" / single.name / "antipodal", half)
    for name in ("summary.json", "summary.md", "timing.json"):
        (half / name).unlink()
    lines = (half / "trials.jsonl").read_text().splitlines(keepends=True)
    (half / "trials.jsonl").write_text("".join(lines[:1]))
    results = run_many([(t, d, tmp_path / "pool" / t.name / d) for t, d in specs], workers=2, progress=False)
    assert [r.ran for r in results] == [3, 2, 2, 2]
    for task, det in specs:
        seq, pool = tmp_path / "seq" / task.name / det, tmp_path / "pool" / task.name / det
        assert (pool / "summary.json").read_bytes() == (seq / "summary.json").read_bytes()
        assert _records(pool) == _records(seq)
        assert json.loads((pool / "timing.json").read_text())["workers"] == 2


def test_a_resume_after_an_objects_files_changed_is_refused_naming_it(tmp_path, object_library, capsys):
    """The run identity holds each imported object's content hash: a re-import between a kill and the resume
    would otherwise mix two meshes in one run."""
    import numpy as np

    from kgn_bench.shapes.mesh_object import content_hashes

    task = tmp_path / "t.toml"
    task.write_text('[task]\nname = "blocks"\nprotocol = "single_object"\ntrials = 2\n'
                    '[objects]\nset = ["test_block"]\n')
    out = tmp_path / "run"
    argv = ["run", str(task), "--detector", "oracle", "--out", str(out), "--quiet"]
    assert main(argv) == 0
    identity = json.loads((out / "run.json").read_text())
    assert set(identity["objects_sha256"]) == {"test_block"} and "detector_fingerprint" not in identity
    assert main(argv) == 0  # nothing changed: the finished run is taken as it is
    grasps = object_library / "test_block" / "grasps.npz"
    backup = tmp_path / "grasps.npz"
    shutil.copy(grasps, backup)
    try:
        with np.load(grasps) as g:  # as a re-import would leave it: other grasps, a manifest that records them
            np.savez(grasps, poses=g["poses"][:-1], widths=g["widths"][:-1])
        manifest_path = object_library / "test_block" / "object.json"
        manifest_backup = manifest_path.read_text()
        manifest = json.loads(manifest_backup)
        manifest["files_sha256"] = content_hashes(object_library / "test_block")
        manifest_path.write_text(json.dumps(manifest))
        capsys.readouterr()
        assert main(argv) == 2
        assert "object test_block changed since the run started" in capsys.readouterr().err
    finally:
        shutil.copy(backup, grasps)
        manifest_path.write_text(manifest_backup)
    assert main(argv) == 0


def test_a_user_detectors_fingerprint_is_recorded_and_checked(tmp_path, capsys, monkeypatch):
    import spoilt_detector

    out = tmp_path / "run"
    argv = ["run", str(_small_task(tmp_path)), "--detector", "spoilt_detector:EveryFifthBlind", "--trials", "1",
            "--out", str(out), "--quiet"]
    assert main(argv) == 0
    assert json.loads((out / "run.json").read_text())["detector_fingerprint"] is None  # none declared: recorded
    monkeypatch.setattr(spoilt_detector.EveryFifthBlind, "fingerprint", "weights-v2", raising=False)
    assert main(argv) == 2
    assert "the fingerprint of detector spoilt_detector:EveryFifthBlind changed" in capsys.readouterr().err


def test_a_run_on_a_bundled_object_shadowed_by_other_content_warns(tmp_path, monkeypatch, capsys):
    """A user's library searched first can hold a stale re-import of a bundled test object: the run goes on
    (an object added with --overwrite is meant to shadow), with a warning naming it."""
    import numpy as np

    from kgn_bench.shapes.library import library_roots
    from kgn_bench.shapes.mesh_object import content_hashes

    user = tmp_path / "lib"
    monkeypatch.setenv("KGN_BENCH_OBJECTS", str(user))
    shutil.copytree(library_roots()[1] / "pb_duck", user / "pb_duck")
    task = tmp_path / "t.toml"
    task.write_text('[task]\nname = "ducks"\nprotocol = "single_object"\ntrials = 1\n[objects]\nset = ["pb_duck"]\n')
    argv = ["run", str(task), "--detector", "oracle", "--out", str(tmp_path / "run"), "--quiet"]
    assert main(argv) == 0
    assert "warning" not in capsys.readouterr().err  # a copy with the same content is no concern
    grasps = user / "pb_duck" / "grasps.npz"
    with np.load(grasps) as g:
        np.savez(grasps, poses=g["poses"][:-1], widths=g["widths"][:-1])
    manifest = json.loads((user / "pb_duck" / "object.json").read_text())
    manifest["files_sha256"] = content_hashes(user / "pb_duck")
    (user / "pb_duck" / "object.json").write_text(json.dumps(manifest))
    assert main([*argv[:5], str(tmp_path / "run2"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert f"warning: task ducks: 1 bundled object(s) are shadowed by other content in {user} (pb_duck)" in err
