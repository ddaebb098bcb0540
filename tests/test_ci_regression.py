"""The CI regression check (docs/reproducibility.md): the fixed-seed clearance task (24 scenes, sized for
the statistical test), the fixed-seed pile task in raw (detector-only) mode and 4 rounds of GIGA's pile protocol
(the floating hand), each with the shipped kgnv2 weights and with the oracle (and the GIGA rounds with the
shipped vgn), against results/ci_baseline.json,
results/ci_baseline_pile.json and results/ci_baseline_giga_pile.json
(`kgn_bench.bench.check`). In the environment the baselines were written in (the portable kernel set, the
lock file's packages) the records must be the baseline's, trial by trial; and a kgnv2 spoilt so that about
one attempt in five fails must fail the statistical test against kgnv2's baseline."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from kgn_bench.bench.check import POWERED_ATTEMPTS
from kgn_bench.cli import main

ROOT = Path(__file__).resolve().parents[1]
CHECKS = {"ci_regression": ROOT / "results" / "ci_baseline.json", "ci_pile": ROOT / "results" / "ci_baseline_pile.json",
          "ci_giga_pile": ROOT / "results" / "ci_baseline_giga_pile.json"}


DETECTORS = {"ci_regression": ("kgnv2", "oracle"), "ci_pile": ("kgnv2", "oracle"),
             "ci_giga_pile": ("kgnv2", "oracle", "vgn")}
"""The detectors each check runs (the Makefile's ``CI_CHECKS``): VGN only in GIGA's protocol, its own."""


@pytest.mark.parametrize("task, detector", [(t, d) for t in CHECKS for d in DETECTORS[t]])
def test_records_and_rates_hold_against_the_baseline(task, detector, session_run, capsys):
    out = session_run(task, detector)
    capsys.readouterr()
    rc = main(["check", str(out), "--baseline", str(CHECKS[task])])
    report = capsys.readouterr().out
    assert rc == 0, f"{detector} regressed on {task}:\n{report}"
    rates = json.loads((out / "summary.json").read_text())["rates"]
    assert {"success", "clear"} <= set(rates)
    # the baselines were written with the lock file's packages and the portable kernels, as CI installs them
    assert report.startswith("exact check") and "records identical to the baseline's" in report, report


def test_the_clearance_task_is_sized_for_the_statistical_test(session_run):
    rates = json.loads((session_run("ci_regression", "kgnv2") / "summary.json").read_text())["rates"]
    assert rates["success"]["n"] >= POWERED_ATTEMPTS


def test_a_kgnv2_blind_at_every_fifth_detection_fails_the_check(tmp_path, capsys):
    out = tmp_path / "spoilt"
    argv = ["run", str(ROOT / "tasks" / "ci_regression.toml"), "--detector", "spoilt_detector:EveryFifthBlind",
            "--workers", "2", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    capsys.readouterr()
    rc = main(["check", str(out), "--baseline", str(CHECKS["ci_regression"]), "--against", "kgnv2"])
    report = capsys.readouterr().out
    assert rc == 1, report
    assert report.startswith("statistical check") and "REGRESSION" in report
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failures"].get("no_candidate", 0) >= 10
