"""The CI regression check (README "Regression check"): the fixed-seed clearance task with the shipped kgnv2
weights and with the oracle; each run's success and clear rates must not fall below results/ci_baseline.json
(Wilson intervals disjoint and lower, `kgn_bench.bench.check`). A change that breaks grasping fails here."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from kgn_bench.cli import main

ROOT = Path(__file__).resolve().parents[1]
TASK = ROOT / "tasks" / "ci_regression.toml"
BASELINE = ROOT / "results" / "ci_baseline.json"


@pytest.mark.parametrize("detector", ["kgnv2", "oracle"])
def test_success_and_clear_rates_hold_against_the_baseline(detector, tmp_path, capsys):
    out = tmp_path / detector
    assert main(["run", str(TASK), "--detector", detector, "--workers", "2", "--quiet", "--out", str(out)]) == 0
    rc = main(["check", str(out), "--baseline", str(BASELINE)])
    report = capsys.readouterr().out
    assert rc == 0, f"{detector} regressed on {TASK.name}:\n{report}"
    rates = json.loads((out / "summary.json").read_text())["rates"]
    assert {"success", "clear"} <= set(rates)
    assert "REGRESSION" not in report and "note:" not in report  # same task, seed and trials as the baseline
