"""The CI regression check (README "Regression check"): the fixed-seed clearance task and the fixed-seed pile task
in raw (detector-only) mode, each with the shipped kgnv2 weights and with the oracle; each run's success and clear
rates must not fall below its baseline in results/ (Wilson intervals disjoint and lower,
`kgn_bench.bench.check`). A change that breaks grasping or the clutter protocol fails here."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from kgn_bench.cli import main

ROOT = Path(__file__).resolve().parents[1]
CHECKS = {"ci_regression": ROOT / "results" / "ci_baseline.json", "ci_pile": ROOT / "results" / "ci_baseline_pile.json"}


@pytest.mark.parametrize("task", list(CHECKS))
@pytest.mark.parametrize("detector", ["kgnv2", "oracle"])
def test_success_and_clear_rates_hold_against_the_baseline(task, detector, session_run, capsys):
    path = ROOT / "tasks" / f"{task}.toml"
    out = session_run(task, detector)
    capsys.readouterr()
    rc = main(["check", str(out), "--baseline", str(CHECKS[task])])
    report = capsys.readouterr().out
    assert rc == 0, f"{detector} regressed on {path.name}:\n{report}"
    rates = json.loads((out / "summary.json").read_text())["rates"]
    assert {"success", "clear"} <= set(rates)
    assert "REGRESSION" not in report and "note:" not in report  # same task, seed and trials as the baseline
