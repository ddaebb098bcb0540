"""Typed trial records: real seeded trials round-trip through their JSON form, every older shape reads with
its defaults and writes back unchanged, and a half-done run written in an older shape resumes identically."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import pytest

from kgn_bench.bench.fingerprint import canonical_sha256
from kgn_bench.bench.records import RECORD_VERSION, AttemptRecord, RecordError, TrialRecord
from kgn_bench.bench.runner import read_trials, run_benchmark
from kgn_bench.bench.stats import summarise
from kgn_bench.bench.trial import run_trial
from kgn_bench.config import load_task
from kgn_bench.detectors import make_detector
from kgn_bench.sim.control import IK

TASKS = Path(__file__).resolve().parents[1] / "tasks"

TRIAL_KEYS = ["index", "protocol", "objects", "placed", "placed_objects", "removed", "attempts", "timing"]
CLUTTER_KEYS = ["index", "protocol", "objects", "placed", "placed_objects", "removed", "attempts", "fell_at_setup",
                "fallen", "timing"]
ATTEMPT_KEYS = ["success", "reason", "object", "candidates", "selected", "score", "grasp", "width", "rejected",
                "detail", "sim_time"]


@pytest.fixture(scope="module")
def real_records():
    """A two-object multi_object round and a three-object pile round with the oracle (seed 0, trial 0)."""
    ik, oracle = IK(), make_detector("oracle")
    multi = replace(load_task(TASKS / "multi_object.toml"), objects_per_scene=2, trials=1)
    pile = replace(load_task(TASKS / "pile.toml"), objects_per_scene=3, trials=1)
    return {"multi": run_trial(multi, 0, oracle, ik), "pile": run_trial(pile, 0, oracle, ik)}


def _as_written(record: TrialRecord) -> dict:
    """The record as a line of trials.jsonl reads back."""
    return json.loads(json.dumps(record.to_json(), sort_keys=True))


def test_real_records_round_trip_in_todays_key_order(real_records):
    multi, pile = real_records["multi"], real_records["pile"]
    assert list(multi.to_json()) == TRIAL_KEYS and list(pile.to_json()) == CLUTTER_KEYS
    for record in (multi, pile):
        assert record.version == RECORD_VERSION and record.attempts
        assert all(list(a.to_json()) == ATTEMPT_KEYS for a in record.attempts)
        back = TrialRecord.from_json(_as_written(record))
        assert back == record and back.to_json() == record.to_json()
        assert json.dumps(back.to_json(), sort_keys=True) == json.dumps(record.to_json(), sort_keys=True)
    executed = [a for a in multi.attempts if a.selected is not None]
    assert executed and all(len(a.grasp) == 7 and a.width > 0 for a in executed)  # world pose, then width (m)
    assert pile.fell_at_setup is not None and pile.placed + pile.fell_at_setup == 3
    assert multi.fell_at_setup is None and multi.fallen is None


def _older(d: dict, version: int) -> dict:
    """Today's record ``d`` in the shape an older version of the code wrote it."""
    d = json.loads(json.dumps(d))
    if version < 4:
        for a in d["attempts"]:
            del a["grasp"], a["width"]
    if version < 2:
        del d["placed_objects"]
    return d


@pytest.mark.parametrize("version", [1, 3])
@pytest.mark.parametrize("kind", ["multi", "pile"])
def test_every_older_shape_reads_with_its_defaults_and_writes_back_unchanged(real_records, kind, version):
    old = _older(_as_written(real_records[kind]), version)
    record = TrialRecord.from_json(old)
    assert record.version == version
    assert record.to_json() == old
    assert list(record.to_json()) == [k for k in (CLUTTER_KEYS if kind == "pile" else TRIAL_KEYS) if k in old]
    assert canonical_sha256(record.to_json()) == canonical_sha256(old)  # the fingerprint of an old run stands
    assert all(a.grasp is None and a.width is None and a.version == 3 for a in record.attempts)
    if version == 1:
        assert record.placed_objects == record.objects  # documented default: every object
    else:
        assert record.placed_objects == real_records[kind].placed_objects


def test_the_fallen_counts_are_none_outside_clutter_and_read_as_written(real_records):
    pile = _as_written(real_records["pile"])
    record = TrialRecord.from_json(pile)
    assert (record.fell_at_setup, record.fallen) == (pile["fell_at_setup"], pile["fallen"])
    multi = TrialRecord.from_json(_as_written(real_records["multi"]))
    assert "fallen" not in multi.to_json() and "fell_at_setup" not in multi.to_json()


def test_a_fault_attempt_and_records_that_are_none():
    fault = AttemptRecord.failed("physics_error", "no stable scene: x")
    assert fault.to_json() == {"success": False, "reason": "physics_error", "object": None, "candidates": 0,
                               "selected": None, "score": None, "grasp": None, "width": None, "rejected": {},
                               "detail": "no stable scene: x", "sim_time": 0.0}
    with pytest.raises(RecordError, match="has no protocol"):
        TrialRecord.from_json({"index": 0})
    with pytest.raises(RecordError, match="JSON object"):
        TrialRecord.from_json([1, 2])
    with pytest.raises(RecordError, match="attempt record has no reason"):
        AttemptRecord.from_json({"success": True})


@pytest.fixture(scope="module")
def full_run(tmp_path_factory):
    """ci_oracle with three objects run to the end: three single-object trials."""
    task = replace(load_task(TASKS / "ci_oracle.toml"), objects=("cuboid", "sphere", "stick"))
    out = tmp_path_factory.mktemp("records") / "full"
    run_benchmark(task, "oracle", out, workers=1, progress=False)
    return task, out


def _less_timing(line: str) -> dict:
    return {k: v for k, v in json.loads(line).items() if k != "timing"}


@pytest.mark.parametrize("version", [1, 3, RECORD_VERSION])
def test_a_half_done_run_in_an_older_shape_resumes_identically(full_run, tmp_path, version):
    """The first trial written as an older version wrote it, the second cut short by a kill: the resume keeps the
    old line byte for byte, reruns the rest as the full run did, and summarises the same."""
    task, full = full_run
    out = tmp_path / "half"
    out.mkdir()
    shutil.copy(full / "run.json", out / "run.json")
    lines = (full / "trials.jsonl").read_text().splitlines(keepends=True)
    first = json.dumps(_older(json.loads(lines[0]), version), sort_keys=True) + "\n"
    (out / "trials.jsonl").write_text(first + lines[1][: len(lines[1]) // 2])
    result = run_benchmark(task, "oracle", out, workers=1, progress=False)
    assert result.ran == 2
    resumed = (out / "trials.jsonl").read_text().splitlines(keepends=True)
    assert resumed[0] == first
    assert [_less_timing(line) for line in resumed[1:]] == [_less_timing(line) for line in lines[1:]]
    assert (out / "summary.json").read_text() == (full / "summary.json").read_text()
    assert (out / "summary.md").read_text() == (full / "summary.md").read_text()
    records = read_trials(out / "trials.jsonl")
    assert [r.version for r in records] == [version, RECORD_VERSION, RECORD_VERSION]
    assert summarise(records, {k: result.summary[k] for k in ("task", "protocol", "detector", "seed")}) \
        == result.summary
