"""The regression check: Wilson-interval comparison of a run's rates with a baseline, and `kgn-bench check`."""

import json

import pytest

from kgn_bench.bench.check import baseline_for, baseline_from_summary, compare, format_check, write_baseline
from kgn_bench.bench.stats import Rate
from kgn_bench.cli import main


def _summary(k, n, clear=None, **identity):
    rates = {"success": Rate(k, n).to_dict()}
    if clear is not None:
        rates["clear"] = Rate(*clear).to_dict()
    ident = {"task": "ci", "protocol": "single_object", "detector": "oracle", "seed": 0, "trials": n}
    ident.update(identity)
    return {**ident, "attempts": n, "rates": rates, "failures": {}, "per_object": {}}


def test_identical_rates_do_not_regress():
    s = _summary(45, 60)
    rows = compare(s, baseline_from_summary(s))
    assert [r.name for r in rows] == ["success"]
    assert rows[0].run == rows[0].baseline == Rate(45, 60)
    assert not rows[0].regressed


@pytest.mark.parametrize(
    "base, run, regressed",
    [
        ((60, 60), (20, 60), True),  # a collapse
        ((60, 60), (57, 60), False),  # within noise
        ((60, 60), (45, 60), True),  # 75 %: upper 84.2 % < lower 94.0 %
        ((30, 60), (20, 60), False),  # overlapping intervals
        ((20, 60), (60, 60), False),  # improvements never fail
        ((5, 6), (0, 6), True),
        ((1, 1), (0, 1), False),  # one trial says nothing
    ],
)
def test_regression_iff_run_interval_is_below_baseline_interval(base, run, regressed):
    rows = compare(_summary(*run), baseline_from_summary(_summary(*base)))
    assert rows[0].regressed is regressed
    assert rows[0].regressed == (Rate(*run).interval[1] < Rate(*base).interval[0])


def test_clear_rate_is_checked_too():
    base = baseline_from_summary(_summary(30, 40, clear=(50, 50), protocol="multi_object"))
    run = _summary(30, 40, clear=(20, 50), protocol="multi_object")
    rows = {r.name: r for r in compare(run, base)}
    assert set(rows) == {"success", "clear"}
    assert not rows["success"].regressed and rows["clear"].regressed


def test_compare_uses_only_shared_rates():
    base = baseline_from_summary(_summary(30, 40, clear=(50, 50)))
    rows = compare(_summary(30, 40), base)  # the run has no clear rate
    assert [r.name for r in rows] == ["success"]
    with pytest.raises(ValueError, match="share no rate"):
        compare(_summary(3, 4), {"rates": {"clear": Rate(1, 1).to_dict()}})


def test_baseline_keeps_identity_and_rates_only(tmp_path):
    s = _summary(50, 60, extra="x")
    b = baseline_from_summary(s)
    assert b == {"task": "ci", "protocol": "single_object", "detector": "oracle", "seed": 0, "trials": 60,
                 "rates": s["rates"]}  # fmt: skip
    write_baseline(s, tmp_path / "b.json")
    assert json.loads((tmp_path / "b.json").read_text()) == {"baselines": {"oracle": b}}


def test_baseline_file_holds_one_entry_per_detector(tmp_path):
    path = tmp_path / "b.json"
    write_baseline(_summary(50, 60, detector="oracle"), path)
    write_baseline(_summary(40, 60, detector="kgnv2"), path)
    write_baseline(_summary(55, 60, detector="oracle"), path)  # replaces oracle's, keeps kgnv2's
    doc = json.loads(path.read_text())
    assert list(doc["baselines"]) == ["kgnv2", "oracle"]
    assert baseline_for(doc, "oracle")["rates"]["success"]["k"] == 55
    assert baseline_for(doc, "kgnv2")["rates"]["success"]["k"] == 40
    with pytest.raises(ValueError, match=r"no baseline for detector 'random' \(it has: kgnv2, oracle\)"):
        baseline_for(doc, "random")
    single = baseline_from_summary(_summary(1, 2))
    assert baseline_for(single, "anything") is single  # a one-baseline file


def test_format_check_verdicts_and_identity_note():
    base = baseline_from_summary(_summary(60, 60))
    text = format_check(compare(_summary(20, 60), base), _summary(20, 60), base)
    assert "REGRESSION" in text and "note" not in text
    other = _summary(57, 60, seed=4)
    text = format_check(compare(other, base), other, base)
    lines = text.splitlines()
    assert lines[1].startswith("success") and lines[1].endswith(" ok")
    assert lines[-1] == "note: run and baseline differ in seed (4 vs 0)"


def _run_dir(tmp_path, summary):
    d = tmp_path / "run"
    d.mkdir()
    (d / "summary.json").write_text(json.dumps(summary))
    return d


def test_cli_check_exit_codes(tmp_path, capsys):
    baseline = tmp_path / "baseline.json"
    good = _run_dir(tmp_path, _summary(60, 60))
    assert main(["check", str(good), "--baseline", str(baseline)]) == 2  # no baseline yet
    assert "--update-baseline" in capsys.readouterr().err
    assert main(["check", str(good), "--baseline", str(baseline), "--update-baseline"]) == 0
    assert json.loads(baseline.read_text())["baselines"]["oracle"]["rates"]["success"]["k"] == 60
    assert str(baseline) in capsys.readouterr().out
    assert main(["check", str(good), "--baseline", str(baseline)]) == 0
    assert "REGRESSION" not in capsys.readouterr().out

    (good / "summary.json").write_text(json.dumps(_summary(57, 60)))
    assert main(["check", str(good), "--baseline", str(baseline)]) == 0
    (good / "summary.json").write_text(json.dumps(_summary(20, 60)))
    assert main(["check", str(good), "--baseline", str(baseline)]) == 1
    out = capsys.readouterr().out
    assert "REGRESSION" in out and "20/60" in out and "60/60" in out
    (good / "summary.json").write_text(json.dumps(_summary(20, 60, detector="kgn")))
    assert main(["check", str(good), "--baseline", str(baseline)]) == 2  # no baseline for this detector
    assert "no baseline for detector 'kgn'" in capsys.readouterr().err


def test_cli_check_bad_inputs(tmp_path, capsys):
    baseline = tmp_path / "baseline.json"
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["check", str(empty), "--baseline", str(baseline), "--update-baseline"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("kgn-bench: error:") and "summary.json not found" in err
    assert not baseline.exists()
    run = _run_dir(tmp_path, _summary(5, 6))
    baseline.write_text("{not json")
    assert main(["check", str(run), "--baseline", str(baseline)]) == 2
    assert "is not valid JSON" in capsys.readouterr().err
    assert main(["check", str(run), "--baseline", str(baseline), "--update-baseline"]) == 2  # not replaced
    assert "is not valid JSON" in capsys.readouterr().err and baseline.read_text() == "{not json"
    for wrong in ([1, 2], {"baselines": [1]}, {"baselines": {"kgnv2": {"rates": {"success": {"k": "x"}}}}},
                  {"rates": {}}, {"rates": {"success": {"k": 3, "n": 2}}}):
        baseline.write_text(json.dumps(wrong))
        assert main(["check", str(run), "--baseline", str(baseline)]) == 2  # 1 is kept for a regression
        err = capsys.readouterr().err
        assert err.startswith(f"kgn-bench: error: baseline {baseline}") and err.count("\n") == 1
    baseline.write_text(json.dumps({"rates": {"clear": Rate(1, 2).to_dict()}}))
    assert main(["check", str(run), "--baseline", str(baseline)]) == 2
    assert "share no rate" in capsys.readouterr().err
    (run / "summary.json").write_text("{")
    assert main(["check", str(run), "--baseline", str(baseline)]) == 2
    assert "not valid JSON" in capsys.readouterr().err
