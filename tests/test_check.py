"""The regression check: exact (record by record) when identity and environment match the baseline's,
Boschloo's one-sided test otherwise, and `kgn-bench check`."""

import json

import pytest

from kgn_bench.bench.check import (
    CheckRow,
    baseline_for,
    baseline_from_run,
    check,
    compare,
    format_check,
    read_run,
    write_baseline,
)
from kgn_bench.bench.stats import Rate
from kgn_bench.cli import main
from kgn_bench.environment import environment

ENV = environment()


def _records(k, n, score=0.5):
    """``n`` single-attempt trial records (JSON form), the first ``k`` successful."""
    return [{"index": i, "protocol": "single_object", "objects": ["cuboid"], "placed": 1, "placed_objects": ["cuboid"],
             "removed": int(i < k),
             "attempts": [{"success": i < k, "reason": None if i < k else "missed", "object": "cuboid",
                           "candidates": 3, "selected": 0, "score": score, "grasp": [0.0] * 7, "width": 0.05,
                           "rejected": {}, "detail": "", "sim_time": 1.0}],
             "timing": {"detect": 0.1 * i}} for i in range(n)]


def _run_dir(path, k, n, detector="oracle", seed=0, env=None, score=0.5):
    """A finished run folder as the runner writes it: run.json, trials.jsonl and summary.json."""
    path.mkdir(parents=True, exist_ok=True)
    identity = {"task": "ci", "protocol": "single_object", "detector": detector, "seed": seed, "trials": n}
    (path / "run.json").write_text(json.dumps({**identity, "commit": "x", "environment": env or ENV}))
    (path / "trials.jsonl").write_text("".join(json.dumps(r) + "\n" for r in _records(k, n, score)))
    summary = {**identity, "attempts": n, "rates": {"success": Rate(k, n).to_dict()}, "failures": {}}
    (path / "summary.json").write_text(json.dumps(summary))
    return path


def test_identical_records_pass_the_exact_check(tmp_path):
    run = read_run(_run_dir(tmp_path / "a", 45, 60))
    result = check(run, baseline_from_run(run))
    assert result.mode == "exact" and result.changes == [] and not result.regressed
    assert "records identical to the baseline's" in format_check(result, run)


def test_a_changed_record_fails_the_exact_check_even_with_equal_rates(tmp_path):
    base = read_run(_run_dir(tmp_path / "a", 45, 60))
    run = read_run(_run_dir(tmp_path / "b", 45, 60, score=0.500001))
    result = check(run, baseline_from_run(base))
    assert result.mode == "exact" and result.regressed and len(result.changes) == 60
    assert result.changes[0] == ("trial 0: attempt 1: cuboid: success (score 0.500000) → "
                                 "cuboid: success (score 0.500001)")
    text = format_check(result, run)
    assert "60 of 60 trials differ" in text and "REGRESSION: the records changed" in text


def test_another_environment_falls_back_to_the_statistical_test(tmp_path):
    base = read_run(_run_dir(tmp_path / "a", 60, 60))
    other = {**ENV, "packages": {**ENV["packages"], "torch": "9.9.9"}}
    run = read_run(_run_dir(tmp_path / "b", 57, 60, env=other))
    result = check(run, baseline_from_run(base))
    assert result.mode == "statistical" and "torch" in result.reason and not result.regressed
    drop = read_run(_run_dir(tmp_path / "c", 45, 60, env=other))
    result = check(drop, baseline_from_run(base))
    assert result.regressed and "REGRESSION" in format_check(result, drop)


def test_another_identity_or_detector_or_no_fingerprint_is_statistical(tmp_path):
    base = read_run(_run_dir(tmp_path / "a", 60, 60))
    seeded = read_run(_run_dir(tmp_path / "b", 60, 60, seed=4))
    assert check(seeded, baseline_from_run(base)).reason == "the run's identity differs from the baseline's (seed)"
    mine = read_run(_run_dir(tmp_path / "c", 60, 60, detector="mod:det"))
    assert "checked against 'oracle'" in check(mine, baseline_from_run(base), against="oracle").reason
    old = {k: v for k, v in baseline_from_run(base).items() if k != "fingerprint"}
    assert "no fingerprint" in check(base, old).reason


@pytest.mark.parametrize("base, run, regressed", [
    ((60, 60), (20, 60), True),   # a collapse
    ((60, 60), (57, 60), False),  # within noise
    ((20, 20), (14, 20), True),   # the interval rule let this pass
    ((30, 60), (20, 60), True),
    ((20, 60), (60, 60), False),  # improvements never fail
    ((1, 1), (0, 1), False),      # one trial says nothing
])  # fmt: skip
def test_statistical_rows_regress_on_a_significant_drop(base, run, regressed):
    row = CheckRow("success", Rate(*base), Rate(*run))
    assert row.regressed is regressed


def test_compare_uses_only_shared_rates():
    summary = {"rates": {"success": Rate(30, 40).to_dict()}}
    rows = compare(summary, {"rates": {"success": Rate(30, 40).to_dict(), "clear": Rate(50, 50).to_dict()}})
    assert [r.name for r in rows] == ["success"]
    with pytest.raises(ValueError, match="share no rate"):
        compare(summary, {"rates": {"clear": Rate(1, 1).to_dict()}})


def test_baseline_file_holds_one_entry_per_detector_with_its_fingerprint(tmp_path):
    path = tmp_path / "b.json"
    write_baseline(read_run(_run_dir(tmp_path / "o", 50, 60, detector="oracle")), path)
    write_baseline(read_run(_run_dir(tmp_path / "k", 40, 60, detector="kgnv2")), path)
    write_baseline(read_run(_run_dir(tmp_path / "o2", 55, 60, detector="oracle")), path)  # replaces oracle's
    doc = json.loads(path.read_text())
    assert list(doc["baselines"]) == ["kgnv2", "oracle"]
    assert baseline_for(doc, "oracle")["rates"]["success"]["k"] == 55
    assert len(baseline_for(doc, "kgnv2")["fingerprint"]["trials"]) == 60
    with pytest.raises(ValueError, match=r"no baseline for detector 'random' \(it has: kgnv2, oracle\)"):
        baseline_for(doc, "random")


def test_cli_check_exit_codes(tmp_path, capsys):
    baseline = tmp_path / "baseline.json"
    good = _run_dir(tmp_path / "run", 60, 60)
    assert main(["check", str(good), "--baseline", str(baseline)]) == 2  # no baseline yet
    assert "--update-baseline" in capsys.readouterr().err
    assert main(["check", str(good), "--baseline", str(baseline), "--update-baseline"]) == 0
    assert "fingerprint of 60 trials" in capsys.readouterr().out
    assert main(["check", str(good), "--baseline", str(baseline)]) == 0
    assert "exact check" in capsys.readouterr().out
    changed = _run_dir(tmp_path / "changed", 60, 60, score=0.4)
    assert main(["check", str(changed), "--baseline", str(baseline)]) == 1
    assert "60 of 60 trials differ" in capsys.readouterr().out
    spoilt = _run_dir(tmp_path / "spoilt", 40, 60, detector="mine:det")
    assert main(["check", str(spoilt), "--baseline", str(baseline)]) == 2  # no baseline of its own
    assert "no baseline for detector 'mine:det'" in capsys.readouterr().err
    assert main(["check", str(spoilt), "--baseline", str(baseline), "--against", "oracle"]) == 1
    out = capsys.readouterr().out
    assert out.startswith("statistical check") and "REGRESSION" in out
    assert main(["check", str(spoilt), "--baseline", str(baseline), "--against", "oracle", "--update-baseline"]) == 2


def test_cli_check_bad_inputs(tmp_path, capsys):
    baseline = tmp_path / "baseline.json"
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["check", str(empty), "--baseline", str(baseline), "--update-baseline"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("kgn-bench: error:") and "summary.json not found" in err
    assert not baseline.exists()
    run = _run_dir(tmp_path / "run", 5, 6)
    baseline.write_text("{not json")
    assert main(["check", str(run), "--baseline", str(baseline)]) == 2
    assert "is not valid JSON" in capsys.readouterr().err
    assert main(["check", str(run), "--baseline", str(baseline), "--update-baseline"]) == 2  # not replaced
    assert "is not valid JSON" in capsys.readouterr().err and baseline.read_text() == "{not json"
    for wrong in ([1, 2], {"baselines": [1]}, {"baselines": {"kgnv2": {"rates": {"success": {"k": "x"}}}}},
                  {"rates": {}}, {"rates": {"success": {"k": 3, "n": 2}}},
                  {"rates": {"success": {"k": 1, "n": 2}}, "fingerprint": {"version": 7}}):
        baseline.write_text(json.dumps(wrong))
        assert main(["check", str(run), "--baseline", str(baseline)]) == 2  # 1 is kept for a regression
        err = capsys.readouterr().err
        assert err.startswith(f"kgn-bench: error: baseline {baseline}") and err.count("\n") == 1
    baseline.write_text(json.dumps({"rates": {"clear": Rate(1, 2).to_dict()}}))
    assert main(["check", str(run), "--baseline", str(baseline)]) == 2
    assert "share no rate" in capsys.readouterr().err
    (run / "trials.jsonl").write_text('{"index": 0}\n')
    assert main(["check", str(run), "--baseline", str(baseline)]) == 2
    assert "line 1 is not a trial record (a trial record has no protocol, objects" in capsys.readouterr().err
    (run / "trials.jsonl").write_text(json.dumps(_records(1, 1)[0]) + "\n")
    assert main(["check", str(run), "--baseline", str(baseline)]) == 2
    assert "is not finished (1 of 6 trials)" in capsys.readouterr().err
    (run / "summary.json").write_text("{")
    assert main(["check", str(run), "--baseline", str(baseline)]) == 2
    assert "not valid JSON" in capsys.readouterr().err
