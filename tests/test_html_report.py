"""The report's HTML page, rendered in headless Chromium: its tables, its chart and its replay links."""

from __future__ import annotations

import shutil
import subprocess

import cv2
import numpy as np
import pytest

from kgn_bench.bench.html_report import page
from kgn_bench.cli import main

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def test_the_page_is_the_markdown_report_with_chart_and_replays(tmp_path):
    text = "# Title\n\n| detector | success |\n|---|---|\n| kgnv2 | 95.0 [76.4, 99.1] (19/20) |\n"
    html = page(text, [{"run": str(tmp_path / "none"), "detector": "kgnv2", "task": "ci"}], tmp_path)
    assert "<table>" in html and "<td>95.0 [76.4, 99.1] (19/20)</td>" in html
    assert '<img src="benchmark.png"' in html and "No run of this report was recorded" in html


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = tmp_path_factory.mktemp("html")
    run = root / "runs" / "ci_oracle"
    assert main(["run", "ci_oracle", "--detector", "oracle", "--quiet", "--record", "--out", str(run)]) == 0
    assert main(["report", str(run), "--out", str(root / "report")]) == 0
    return root / "report"


def _chromium(*args: str, cwd) -> subprocess.CompletedProcess:
    if CHROMIUM is None:  # .ci/run installs Debian's chromium; a machine without it cannot run this test
        pytest.skip("no chromium on this machine (apt-get install chromium)")
    return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={cwd / 'profile'}", *args], capture_output=True,
                          text=True, timeout=120, check=True, cwd=cwd)


def test_chromium_shows_the_tables_the_chart_and_a_replay_link(report, tmp_path):
    url = (report / "benchmark.html").as_uri()
    dom = _chromium("--dump-dom", url, cwd=tmp_path).stdout
    assert "KGN-Bench closed-loop benchmark" in dom
    assert "<td>oracle</td>" in dom and "100.0 [61.0, 100.0] (6/6)" in dom  # the table with its interval
    assert "Failure reasons" in dom and '<img src="benchmark.png"' in dom
    assert 'href="../runs/ci_oracle/recording.rrd"' in dom and "kgn-bench replay" in dom
    shot = tmp_path / "shot.png"
    _chromium("--window-size=1200,2400", f"--screenshot={shot}", url, cwd=tmp_path)
    image = cv2.imread(str(shot))
    assert image is not None and image.shape[:2] == (2400, 1200)
    # the chart loaded from disk: matplotlib's first colour (#1f77b4, BGR 180 119 31) fills its bars
    bars = np.all(np.abs(image.astype(int) - (180, 119, 31)) < 12, axis=2)
    assert bars.sum() > 2000
