"""The perf commands print their figures: dataset generation, detector timing, imports and the backends."""

import pytest

from kgn_bench.bench.perf import perf_data, perf_train


def test_perf_data_reports_views_per_second_and_the_split():
    report = perf_data(scenes=1, workers=1, mode="single", views=1)
    assert "views/s" in report
    for stage in ("settle", "annotate", "render", "write"):
        assert f"| {stage} |" in report


def test_perf_detector_times_any_non_privileged_detector(tiny_dataset):
    from kgn_bench.bench.perf import perf_detector

    root, _ = tiny_dataset
    text = perf_detector("antipodal", frames=1, threads=1, data=root)
    assert "detector antipodal" in text and "| detect |" in text and "frames/s" in text
    with pytest.raises(ValueError, match="privileged"):
        perf_detector("oracle", frames=1, data=root)


def test_perf_import_times_each_stage():
    from kgn_bench.bench.perf import perf_import

    report = perf_import(faces=1000, verify=24, hulls=2)
    assert "1000 faces" in report and "wall:" in report
    for stage in ("repair", "decompose", "sample", "verify", "preview"):
        assert f"| {stage} |" in report


def test_perf_backends_times_each_backend_and_requires_the_same_summary(tmp_path):
    """Two real `kgn-bench run` commands, the local pool and a Ray each starts for itself (~10 s)."""
    from kgn_bench.bench.perf import PerfError, perf_backends

    report = perf_backends("tasks/ci_oracle.toml", detector="oracle", workers=2, rounds=1)
    assert "| local pool | Ray started by the command |" in report
    row = next(line for line in report.splitlines() if line.startswith("| mean |"))
    assert row.count(" s") == 2 and "%" in row
    assert "byte-identical in all 2 runs" in report
    with pytest.raises(PerfError, match=r"on the local pool failed .*no_such_detector"):
        perf_backends("tasks/ci_oracle.toml", detector="no_such_detector", rounds=1)


def test_perf_train_splits_a_step_into_batch_preparation_and_the_step(tiny_dataset):
    root, _ = tiny_dataset
    text = perf_train(root, strides=(4, 2), precisions=("float32",), batches=2, batch_size=2)
    rows = [line for line in text.splitlines() if line.startswith("| 4 |") or line.startswith("| 2 |")]
    assert len(rows) == 4 and "kernels:" in text
    for row, layout in zip(rows, ["contiguous", "channels-last"] * 2):
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[1:3] == ["float32", layout] and all(float(c) > 0 for c in cells[3:])
