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


def test_runs_of_several_seeds_are_one_cell_pooled_with_the_mean_and_std_of_the_seeds(tmp_path):
    runs = []
    for seed, (k, n) in enumerate([(60, 100), (70, 100), (80, 100)]):
        f = _run(tmp_path / f"seed{seed}", "single_object", "kgnv2", (k, n), failures={"missed": n - k},
                 per_object={"cube": (k // 2, n // 2)})
        s = json.loads((f / "summary.json").read_text())
        s["seed"] = seed
        (f / "summary.json").write_text(json.dumps(s))
        runs.append(f)
    text, payload = build_report(load_summaries(runs))
    cell = payload["detectors"]["kgnv2"]["single, primitives"]
    assert (cell["k"], cell["n"]) == (210, 300)  # pooled
    assert cell["per_seed"] == [0.6, 0.7, 0.8]
    assert cell["mean"] == pytest.approx(0.7) and cell["std"] == pytest.approx(0.0816497, abs=1e-6)  # ddof = 0
    assert "70.0 ± 8.2 over 3 seeds" in text
    assert payload["failures"]["kgnv2"]["missed"] == 90
    assert payload["per_object"]["single_object"]["kgnv2"]["cube"]["n"] == 150
    twin = _run(tmp_path / "twin", "single_object", "kgnv2", (1, 2))  # seed 0 again
    with pytest.raises(ReportError, match="same seed"):
        build_report(load_summaries([*runs, twin]))


def _clutter(folder, task, protocol, detector, success, clear, fallen=0, fell_at_setup=0):
    """A run folder of a clutter protocol (``pile``, ``giga_pile``, ...): GSR, DR and the objects that left."""
    f = _run(folder, task, detector, success, clear=clear)
    s = json.loads((f / "summary.json").read_text())
    s.update(protocol=protocol, fell_at_setup=fell_at_setup, fallen=fallen)
    (f / "summary.json").write_text(json.dumps(s))
    return f


def test_the_hard_tier_is_its_own_table_with_gsr_dr_fallen_and_giga(tmp_path):
    hard = _clutter
    runs = [_run(tmp_path / "a", "single_object", "kgnv2", (114, 120)),
            hard(tmp_path / "b", "pile", "pile", "kgnv2", (30, 60), (30, 50), 2),
            hard(tmp_path / "c", "pile_assisted", "pile", "kgnv2", (45, 60), (45, 50), 0),
            hard(tmp_path / "d", "packed", "packed", "oracle", (49, 50), (49, 50), 0)]
    text, payload = build_report(load_summaries(runs), tmp_path / "out")
    lines = text.splitlines()
    main_header = next(line for line in lines if line.startswith("| detector | single"))
    assert "pile" not in main_header  # the clutter runs are not main-table columns
    i = lines.index("## Hard tier: pile and packed clutter")
    header = next(line for line in lines[i:] if line.startswith("| detector |"))
    assert header == "| detector | packed GSR | packed DR | pile GSR | pile DR | pile_assisted GSR | pile_assisted DR |"
    kgnv2 = next(line for line in lines[i:] if line.startswith("| kgnv2 |"))
    assert kgnv2.startswith("| kgnv2 | — | — | 50.0") and "(45/50)" in kgnv2
    assert "kgnv2 pile: 0 while building, 2 during the rounds" in text
    assert "| GIGA (published) | 83.5 | 84.3 | 69.3 | 49.8 |" in text and "free-floating hand" in text
    assert payload["fallen"]["kgnv2/pile"] == {"fell_at_setup": 0, "fallen": 2}
    assert payload["detectors"]["oracle"]["packed success"]["k"] == 49


def _with_environment(folder, env):
    (folder / "run.json").write_text(json.dumps({"environment": env}))
    return folder


def test_the_environment_line_says_whether_the_cpu_matters(tmp_path):
    from kgn_bench.bench.report import environment_warnings
    from kgn_bench.environment import environment

    env = environment()
    portable = {**env, "kernels": {"set": "x86-64-v3", "reason": "", "effective": {}}}
    native = {**env, "kernels": {"set": "native", "reason": "KGN_BENCH_KERNELS=native", "effective": {}}}
    a = _with_environment(_run(tmp_path / "a", "single_object", "kgnv2", (10, 12)), portable)
    b = _with_environment(_run(tmp_path / "b", "single_object", "oracle", (12, 12)), {**portable, "cpu": "Other CPU"})
    summaries = load_summaries([a, b])
    text, _ = build_report(summaries)
    assert "with the portable x86-64-v3 kernels (any x86-64 CPU with AVX2 gives the same records" in text
    assert environment_warnings(summaries) == []
    for folder, e in ((a, native), (b, {**native, "cpu": "Other CPU"})):
        _with_environment(folder, e)
    summaries = load_summaries([a, b])
    text, _ = build_report(summaries)
    assert "Environment: MIXED" in text
    (warning,) = environment_warnings(summaries)
    assert warning.endswith("→ Other CPU")


def _section(text, title):
    """The lines of the report's section ``## title`` (up to the next ``## ``), or of its head before any."""
    lines = text.splitlines()
    start = lines.index(f"## {title}") if title else 0
    end = next((i for i in range(start + 1, len(lines)) if lines[i].startswith("## ")), len(lines))
    return lines[start:end]


def _cell(k, n):
    return str(Rate(k, n)).replace(" %", "")


def test_gigas_protocol_is_a_third_table_beside_table_i_and_leaves_the_others_alone(tmp_path):
    from kgn_bench.bench.report import GIGA_PROTOCOLS

    assert GIGA_PROTOCOLS == ("giga_pile", "giga_packed")
    others = [_run(tmp_path / "main", "single_object", "kgnv2", (114, 120)),
              _clutter(tmp_path / "hard", "pile", "pile", "antipodal", (30, 60), (30, 50), fallen=2)]
    giga = [_clutter(tmp_path / "g1", "giga_pile", "giga_pile", "antipodal", (40, 80), (40, 100), fallen=1),
            _clutter(tmp_path / "g2", "giga_pile", "giga_pile", "vgn", (55, 90), (55, 100)),
            _clutter(tmp_path / "g3", "giga_packed", "giga_packed", "antipodal", (70, 95), (70, 100)),
            _clutter(tmp_path / "g4", "giga_packed", "giga_packed", "vgn", (60, 85), (60, 100), fell_at_setup=3)]
    before, before_payload = build_report(load_summaries(others), tmp_path / "before")
    text, payload = build_report(load_summaries(others + giga), tmp_path / "out")

    # the main table and the hard tier print exactly what they printed without the GIGA-protocol runs
    hard = "Hard tier: pile and packed clutter"
    assert _section(text, None) == _section(before, None)
    assert _section(text, hard) == _section(before, hard)
    assert not any("giga" in line for line in _section(text, None) + _section(text, hard))

    section = _section(text, "GIGA's protocol (calibration)")
    header = next(line for line in section if line.startswith("| detector |"))
    assert header == "| detector | giga_packed GSR | giga_packed DR | giga_pile GSR | giga_pile DR |"
    rows = [line for line in section if line.startswith("| ") and line != header]
    assert rows[:2] == [f"| vgn | {_cell(60, 85)} | {_cell(60, 100)} | {_cell(55, 90)} | {_cell(55, 100)} |",
                        f"| antipodal | {_cell(70, 95)} | {_cell(70, 100)} | {_cell(40, 80)} | {_cell(40, 100)} |"]
    assert rows[2:] == ["| SHAF (published) | 56.6 ± 2.0 | 58.0 ± 3.0 | 50.7 ± 1.7 | 42.6 ± 2.8 |",
                        "| GPD (published) | 35.4 ± 1.9 | 30.7 ± 2.0 | 17.7 ± 2.3 | 9.2 ± 1.3 |",
                        "| VGN (published) | 74.5 ± 1.3 | 79.2 ± 2.3 | 60.7 ± 4.2 | 44.0 ± 4.9 |",
                        "| GIGA-Aff (published) | 77.2 ± 2.3 | 78.9 ± 1.7 | 67.8 ± 3.0 | 49.7 ± 1.9 |",
                        "| GIGA (published) | 83.5 ± 2.4 | 84.3 ± 2.2 | 69.3 ± 3.3 | 49.8 ± 3.9 |",
                        "| GIGA (HR) (published) | 87.9 ± 3.0 | 86.0 ± 3.2 | 69.8 ± 3.2 | 51.1 ± 2.8 |"]
    assert not any(line.startswith("| kgnv2 |") for line in section)  # kgnv2 ran no GIGA round
    note = " ".join(section)
    assert "antipodal giga_pile: 0 while building, 1 during the rounds" in note
    assert "vgn giga_packed: 3 while building, 0 during the rounds" in note
    for differs in ("MuJoCo instead of PyBullet", "43 real test objects", "mean ± population std",
                    "GPD ↔ `antipodal`", "VGN ↔ `vgn`"):
        assert differs in note
    assert text.index("## Hard tier") < text.index("## GIGA's protocol") < text.index("## Failure reasons")

    assert before_payload["columns"] == [c for c in payload["columns"] if c["tier"] != "giga"]
    tiers = {c["label"]: c["tier"] for c in payload["columns"]}
    assert tiers == {"single, primitives": "main", "pile success": "hard", "pile clear": "hard",
                     "giga_packed success": "giga", "giga_packed clear": "giga",
                     "giga_pile success": "giga", "giga_pile clear": "giga"}
    assert payload["detectors"]["vgn"]["giga_pile success"] == Rate(55, 90).to_dict()
    assert payload["detectors"]["antipodal"]["giga_packed clear"]["k"] == 70
    assert payload["detectors"]["kgnv2"]["giga_pile success"] is None
    assert payload["giga_table_i"]["pile"]["VGN"] == {"gsr": {"mean": 60.7, "std": 4.2},
                                                      "dr": {"mean": 44.0, "std": 4.9}}
    assert payload["giga"] == before_payload["giga"] and set(payload["giga"]["pile"]) == {"GPD", "VGN", "GIGA"}
    assert payload["giga_family"] == {"GPD": "antipodal", "VGN": "vgn"}
    assert payload["fallen"]["vgn/giga_packed"] == {"fell_at_setup": 3, "fallen": 0}

    html = (tmp_path / "out" / "benchmark.html").read_text()
    assert "<h2>GIGA's protocol (calibration)</h2>" in html and "<td>74.5 ± 1.3</td>" in html
    chart, chart_before = (cv2.imread(str(tmp_path / d / "benchmark.png")) for d in ("out", "before"))
    assert chart.shape[0] == chart_before.shape[0] and chart.shape[1] > chart_before.shape[1]  # 4 more groups


def test_a_report_of_one_giga_scene_shows_only_its_columns_and_reads_bundles(tmp_path):
    from kgn_bench.bench.bundle import FORMAT, VERSION

    folder = _clutter(tmp_path / "run", "giga_pile", "giga_pile", "vgn", (55, 90), (55, 100))
    summary = json.loads((folder / "summary.json").read_text())
    bundle = tmp_path / "bundle" / "vgn"
    bundle.mkdir(parents=True)
    (bundle / "bundle.json").write_text(json.dumps({
        "format": FORMAT, "version": VERSION, "detector": "vgn",
        "runs": [{"task": "giga_pile", "protocol": "giga_pile", "summary": summary, "environment": None}]}))
    text, payload = build_report(load_summaries([bundle]))
    assert "| detector | single" not in text and "## Hard tier" not in text  # no main table, no hard tier
    section = _section(text, "GIGA's protocol (calibration)")
    assert section[section.index("| detector | giga_pile GSR | giga_pile DR |") + 2:][:3] == [
        f"| vgn | {_cell(55, 90)} | {_cell(55, 100)} |",
        "| SHAF (published) | 50.7 ± 1.7 | 42.6 ± 2.8 |", "| GPD (published) | 17.7 ± 2.3 | 9.2 ± 1.3 |"]
    assert f"`{bundle}:giga_pile`" in text and payload["detectors"]["vgn"]["giga_pile clear"]["k"] == 55
