"""The benchmark report from run summaries: table cells, paper rows, failure sums, the chart, bad folders."""

from __future__ import annotations

import json

import cv2
import pytest

from kgn_bench.bench.report import ReportError, build_report, load_summaries
from kgn_bench.bench.stats import Rate


def _run(folder, task, detector, success, clear=None, failures=None, per_object=None):
    """Write a run folder whose summary has ``success`` = (k, n), optionally ``clear`` and per-object (k, n)."""
    rates = {"success": Rate(*success).to_dict()}
    if clear is not None:
        rates["clear"] = Rate(*clear).to_dict()
    summary = {"task": task, "detector": detector, "protocol": "multi_object" if clear else "single_object",
               "seed": 0, "trials": success[1], "attempts": success[1], "rates": rates,
               "failures": {"missed": 0, "collision": 0, **(failures or {})},
               "per_object": {name: Rate(*kn).to_dict() for name, kn in (per_object or {}).items()}}
    folder.mkdir(parents=True)
    (folder / "summary.json").write_text(json.dumps(summary))
    return folder


def test_report_rows_columns_paper_and_failures(tmp_path):
    runs = [
        _run(tmp_path / "a", "single_object", "kgnv2", (114, 120), failures={"missed": 4, "collision": 2},
             per_object={"ring": (55, 60), "cuboid": (59, 60)}),
        _run(tmp_path / "b", "single_household", "kgnv2", (108, 120), failures={"missed": 12},
             per_object={"mug": (54, 60), "can": (54, 60)}),
        _run(tmp_path / "c", "multi_object", "kgnv2", (150, 170), clear=(148, 150), failures={"collision": 20}),
        _run(tmp_path / "d", "single_object", "oracle", (119, 120), per_object={"ring": (60, 60)}),
        _run(tmp_path / "e", "my_task", "random", (3, 60)),
    ]
    text, payload = build_report(load_summaries(runs), tmp_path / "out")
    header = next(line for line in text.splitlines() if line.startswith("| detector | single"))
    assert header == ("| detector | single, primitives | single, household | multi success | multi clear "
                      "| my_task success |")
    kgnv2 = next(line for line in text.splitlines() if line.startswith("| kgnv2 |"))
    assert f"| {str(Rate(114, 120)).replace(' %', '')} |" in kgnv2 and "(148/150)" in kgnv2
    assert kgnv2.endswith("| — |")  # no my_task run for kgnv2
    paper = next(line for line in text.splitlines() if line.startswith("| kgnv2 (paper, real robot) |"))
    assert "| — | 92.5 ± 6.7 (n=40) | — |" in paper
    assert [d for d in payload["detectors"]] == ["kgnv2", "random", "oracle"]  # fixed detector order
    assert payload["failures"]["kgnv2"]["missed"] == 16 and payload["failures"]["kgnv2"]["collision"] == 22
    assert payload["detectors"]["oracle"]["single, primitives"]["k"] == 119
    lines = text.splitlines()
    at = lines.index("**single_object** (success)")
    assert lines[at + 2: at + 6] == ["| detector | cuboid | ring |", "|---|---:|---:|",
                                     "| kgnv2 | 98 (59/60) | 92 (55/60) |", "| oracle | — | 100 (60/60) |"]
    assert "**multi_object**" not in text  # no per-object rates in that run
    assert payload["per_object"]["single_object"]["oracle"]["ring"]["k"] == 60
    assert text.index("**single_object**") < text.index("**single_household**")  # column order
    text_reversed, _ = build_report(load_summaries(runs[::-1]))  # the report command finds runs in path order
    assert text_reversed.split("## Per object")[1].split("Runs:")[0] == text.split("## Per object")[1].split("Runs:")[0]
    img = cv2.imread(str(tmp_path / "out" / "benchmark.png"))
    assert img is not None and img.shape[0] == 540  # 3.6 in at 150 dpi
    assert (tmp_path / "out" / "benchmark.md").read_text() == text


def test_bad_run_folders_are_named(tmp_path):
    with pytest.raises(ReportError, match=r"no summary\.json"):
        load_summaries([tmp_path / "missing"])
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "summary.json").write_text("{not json")
    with pytest.raises(ReportError, match="not valid JSON"):
        load_summaries([tmp_path / "junk"])
    (tmp_path / "junk" / "summary.json").write_text('{"task": "x"}')
    with pytest.raises(ReportError, match="no detector, rates, failures"):
        load_summaries([tmp_path / "junk"])
    a = _run(tmp_path / "a", "single_object", "kgnv2", (1, 2))
    b = _run(tmp_path / "b", "single_object", "kgnv2", (2, 2))
    with pytest.raises(ReportError, match="two runs of single_object with kgnv2"):
        build_report(load_summaries([a, b]))
    with pytest.raises(ReportError, match="no runs"):
        build_report([])
