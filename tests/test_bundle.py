"""Results bundles: `kgn-bench export` writes one per detector, and `kgn-bench report` reads them like runs."""

from __future__ import annotations

import csv
import json

import pytest

from kgn_bench.bench.bundle import ATTEMPT_COLUMNS, BundleError, export_bundles, read_bundle
from kgn_bench.bench.fingerprint import canonical_sha256
from kgn_bench.cli import main


@pytest.fixture(scope="module")
def oracle_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "ci_oracle"
    assert main(["run", "ci_oracle", "--detector", "oracle", "--quiet", "--out", str(out)]) == 0
    return out


def test_a_bundle_holds_summary_attempts_config_environment_and_card(oracle_run, tmp_path):
    (bundle,) = export_bundles([oracle_run], tmp_path / "bundles")
    assert bundle.name == "oracle" and oct(bundle.stat().st_mode & 0o777) == "0o755"
    doc = json.loads((bundle / "bundle.json").read_text())
    assert doc["format"] == "kgn-bench-results" and doc["version"] == 1 and doc["detector"] == "oracle"
    (entry,) = doc["runs"]
    run = json.loads((oracle_run / "run.json").read_text())
    config = json.loads((bundle / entry["config"]).read_text())
    assert config == run["config"] and entry["config_sha256"] == canonical_sha256(config)
    assert entry["summary"] == json.loads((oracle_run / "summary.json").read_text())
    assert entry["environment"]["kernels"]["set"] in ("x86-64-v3", "native")
    rows = list(csv.DictReader((bundle / entry["attempts"]).open()))
    assert tuple(rows[0]) == ATTEMPT_COLUMNS
    records = [json.loads(line) for line in (oracle_run / "trials.jsonl").read_text().splitlines()]
    assert len(rows) == sum(len(r["attempts"]) for r in records) == entry["summary"]["attempts"]
    done = [r for r in rows if r["success"] == "1"]
    assert done and all(r["width"] and r["qw"] for r in done)  # the executed grasp's pose and opening
    first = sorted(records, key=lambda r: r["index"])[0]["attempts"][0]
    assert [float(rows[0][k]) for k in ("x", "y", "z", "qw", "qx", "qy", "qz")] == first["grasp"]
    assert "Built-in detector" in (bundle / "card.md").read_text()


def test_report_reads_bundles_like_run_folders(oracle_run, tmp_path, capsys):
    export_bundles([oracle_run], tmp_path / "board")
    capsys.readouterr()
    assert main(["report", str(tmp_path / "board"), "--out", str(tmp_path / "a")]) == 0
    assert main(["report", str(oracle_run), "--out", str(tmp_path / "b")]) == 0
    from_bundle = json.loads((tmp_path / "a" / "benchmark.json").read_text())
    from_run = json.loads((tmp_path / "b" / "benchmark.json").read_text())
    assert from_bundle["detectors"] == from_run["detectors"] and from_bundle["failures"] == from_run["failures"]


def test_export_refuses_duplicates_and_existing_bundles_and_reading_checks_the_format(oracle_run, tmp_path, capsys):
    with pytest.raises(BundleError, match="two runs of ci_oracle with oracle"):
        export_bundles([oracle_run, oracle_run], tmp_path / "x")
    export_bundles([oracle_run], tmp_path / "y")
    assert main(["export", str(oracle_run), "--out", str(tmp_path / "y")]) == 2
    assert "exists; use --overwrite" in capsys.readouterr().err
    assert main(["export", str(oracle_run), "--out", str(tmp_path / "y"), "--overwrite"]) == 0
    doc = tmp_path / "y" / "oracle" / "bundle.json"
    doc.write_text(json.dumps({**json.loads(doc.read_text()), "version": 99}))
    with pytest.raises(BundleError, match="bundle version 99"):
        read_bundle(doc.parent)
    assert main(["report", str(doc.parent), "--out", str(tmp_path / "r")]) == 2
    unfinished = tmp_path / "cut"
    unfinished.mkdir()
    for name in ("run.json", "summary.json"):
        (unfinished / name).write_text((oracle_run / name).read_text())
    (unfinished / "trials.jsonl").write_text((oracle_run / "trials.jsonl").read_text().splitlines(True)[0])
    assert main(["export", str(unfinished), "--out", str(tmp_path / "z")]) == 2
    assert "is not finished" in capsys.readouterr().err
