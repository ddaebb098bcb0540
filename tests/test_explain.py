"""`kgn-bench eval trial`: a recorded attempt re-created up to its selection, the chosen grasp measured against the
true grasps; on the CI regression runs (real MuJoCo, the shipped kgnv2, the oracle)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import pytest

from kgn_bench.cli import main
from kgn_bench.eval.explain import (
    CATEGORIES,
    ExplainError,
    GraspError,
    TrialExplanation,
    category,
    explain_failures,
    explain_trial,
)


@pytest.mark.parametrize("detector", ["kgnv2", "oracle"])
def test_the_recreated_first_selection_is_the_recorded_one(detector, session_run):
    run = session_run("ci_regression", detector)
    x = explain_trial(run, 0)
    assert x.same_as_recorded and not x.weights_changed
    assert x.selected is not None and x.candidate is not None and x.executed is not None
    for e in (x.candidate, x.executed):
        assert all(math.isfinite(v) for v in (e.centre_cm, e.ray_cm, e.rotation_deg, e.width_cm))
    assert 0 <= x.top_matched <= x.top <= 10 and 0 <= x.matched <= x.candidates
    assert x.image.shape == (480, 1280, 3)
    if detector == "oracle":  # its candidates are true grasps: each matches, the chosen one exactly as ranked
        assert x.matched == x.candidates and x.candidate.matched
        assert x.candidate.centre_cm < 0.3 and abs(x.candidate.ray_cm) < 0.3 and abs(x.candidate.width_cm) < 1e-6


def test_a_later_attempt_of_a_round_is_re_created_after_the_earlier_ones(session_run):
    run = session_run("ci_regression", "kgnv2")
    records = [json.loads(line) for line in (run / "trials.jsonl").read_text().splitlines()]
    record = next(r for r in records if len(r["attempts"]) >= 2)
    x = explain_trial(run, record["index"], attempt=2)
    assert x.attempt == 2 and x.same_as_recorded
    assert x.recorded["reason"] == record["attempts"][1]["reason"] and x.selected == record["attempts"][1]["selected"]
    with pytest.raises(ExplainError, match=f"has no attempt {len(record['attempts']) + 1}"):
        explain_trial(run, record["index"], attempt=len(record["attempts"]) + 1)


def test_cli_writes_the_report_and_refuses_what_it_cannot_explain(session_run, tmp_path, capsys):
    run = session_run("ci_regression", "oracle")
    out = tmp_path / "explain"
    assert main(["eval", "trial", str(run), "--trial", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "# Trial 1, attempt 1 of" in printed and "| candidate (as predicted) |" in printed
    data = json.loads((out / "explain.json").read_text())
    assert data["index"] == 1 and data["same_as_recorded"] and data["detector"] == "oracle"
    assert (out / "explain.png").stat().st_size > 10_000 and (out / "explain.md").read_text().startswith("# Trial 1,")

    assert main(["eval", "trial", str(tmp_path), "--trial", "0", "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert "not a run folder (no run.json)" in err and err.count("\n") == 1
    assert main(["eval", "trial", str(run), "--trial", "999", "--out", str(tmp_path / "b")]) == 2
    assert "trial 999 is out of range" in capsys.readouterr().err
    assert not (tmp_path / "b" / "explain.json").exists()


def test_a_trial_without_a_record_is_refused(session_run, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    src = session_run("ci_regression", "oracle")
    (run / "run.json").write_text((src / "run.json").read_text())
    (run / "trials.jsonl").write_text("")
    with pytest.raises(ExplainError, match="trial 0 has no record"):
        explain_trial(run, 0)
    (run / "run.json").write_text('{"detector": "oracle", "config": {"name": "x"}}')
    with pytest.raises(ExplainError, match="needs 'protocol'"):
        explain_trial(run, 0)


def test_a_run_folder_never_makes_the_tool_import_code_named_in_it(session_run, tmp_path, capsys):
    """Run folders are shared between labs: a detector named module:attribute inside one is not imported
    unless the command line names it too."""

    run = tmp_path / "run"
    run.mkdir()
    src = session_run("ci_regression", "oracle")
    identity = json.loads((src / "run.json").read_text())
    (run / "run.json").write_text(json.dumps({**identity, "detector": "os:abort"}))
    (run / "trials.jsonl").write_text((src / "trials.jsonl").read_text())
    for argv in (["eval", "trial", str(run), "--trial", "0"], ["eval", "failures", str(run), "--quiet"]):
        assert main(argv) == 2
        assert "is code outside kgn-bench" in capsys.readouterr().err
    assert main(["eval", "trial", str(run), "--trial", "0", "--detector", "mine:det"]) == 2
    assert "ran detector 'os:abort', not 'mine:det'" in capsys.readouterr().err

def _explained(candidate: GraspError | None, executed: GraspError | None) -> TrialExplanation:
    return TrialExplanation(run="r", task="t", detector="d", index=0, attempt=1, objects=["cuboid"], recorded={},
                            candidates=1, selected=None if candidate is None else 0, rejected={},
                            candidate=candidate, executed=executed, top_matched=0, top=1, matched=0,
                            same_as_recorded=True)

@pytest.mark.parametrize(("terms", "executed_matched", "expected"), [
    (None, None, "no_grasp"),
    ("selected", None, "no_truth"),
    ((0.2, 0.1, 35.0, 0.0, False), False, "rotation"),
    ((0.2, -1.4, 5.0, 0.0, False), False, "scale"),
    ((1.3, 0.2, 5.0, 0.0, False), False, "centre"),
    ((0.8, 0.8, 5.0, 0.0, False), False, "position"),
    ((0.2, 0.1, 5.0, -2.3, True), True, "width"),
    ((0.2, 0.1, 5.0, 0.2, True), False, "moved_by_selector"),
    ((0.2, 0.1, 5.0, 0.2, True), True, "execution"),
])
def test_a_failure_falls_in_the_first_category_whose_rule_holds(terms, executed_matched, expected):
    if terms is None:
        x = _explained(None, None)
    elif terms == "selected":  # a grasp was chosen, but there was no true grasp to measure it against
        x = replace(_explained(None, None), selected=3)
    else:
        centre, ray, rot, width, matched = terms
        c = GraspError(centre * 20, centre, ray, rot, width, matched)
        x = _explained(c, GraspError(0.0, 0.0, 0.0, 0.0, 0.0, executed_matched))
    assert category(x) == expected and expected in CATEGORIES

def test_every_failed_attempt_of_a_run_is_explained_and_counted(session_run, tmp_path, capsys):
    run = session_run("ci_pile", "kgnv2")
    records = [json.loads(line) for line in (run / "trials.jsonl").read_text().splitlines()]
    failed = sorted((r["index"], k) for r in records for k, a in enumerate(r["attempts"], 1) if not a["success"])
    study = explain_failures(run, progress=False)
    got = sorted([(x.index, x.attempt) for x in study.explanations]
                 + [(f["index"], f["attempt"]) for f in study.faults])
    assert got == failed and study.attempts == sum(len(r["attempts"]) for r in records)
    assert all(x.same_as_recorded for x in study.explanations)
    assert sum(study.counts().values()) == len(failed)
    assert main(["eval", "failures", str(run), "--quiet", "--out", str(tmp_path)]) == 0
    assert f"{len(failed)} of {study.attempts} attempts failed" in capsys.readouterr().out
    data = json.loads((tmp_path / "failures.json").read_text())
    assert data["counts"] == study.counts() and len(data["failures"]) == len(study.explanations)


def test_an_unfinished_run_is_read_without_writing_and_its_coverage_said(session_run, tmp_path, capsys):
    src = session_run("ci_regression", "oracle")
    run = tmp_path / "cut"
    run.mkdir()
    (run / "run.json").write_text((src / "run.json").read_text())
    clean = next(line for line in (src / "trials.jsonl").read_text().splitlines()
                 if all(a["success"] for a in json.loads(line)["attempts"]))
    text = clean + "\n" + '{"index": 7, "attem'  # a run killed while writing its second record
    (run / "trials.jsonl").write_text(text)
    assert main(["eval", "failures", str(run), "--quiet", "--out", str(tmp_path / "x")]) == 0
    assert "this covers the 1 of its 24 trials that have a record" in capsys.readouterr().out
    assert (run / "trials.jsonl").read_text() == text  # a reader does not repair another process's file
    data = json.loads((tmp_path / "x" / "failures.json").read_text())
    assert (data["trials"], data["planned_trials"]) == (1, 24)
