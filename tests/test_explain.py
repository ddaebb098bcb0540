"""`kgn-bench eval trial`: a recorded attempt re-created up to its selection, the chosen grasp measured against the
true grasps; on the CI regression runs (real MuJoCo, the shipped kgnv2, the oracle)."""

from __future__ import annotations

import json
import math

import pytest

from kgn_bench.cli import main
from kgn_bench.eval.explain import ExplainError, explain_trial


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
