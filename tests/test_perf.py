"""The perf commands print their figures: dataset generation and detector timing."""

import pytest

from kgn_bench.perf import perf_data


def test_perf_data_reports_views_per_second_and_the_split():
    report = perf_data(scenes=1, workers=1, mode="single", views=1)
    assert "views/s" in report
    for stage in ("settle", "annotate", "render", "write"):
        assert f"| {stage} |" in report


def test_perf_detector_times_any_non_privileged_detector(tiny_dataset):
    from kgn_bench.perf import perf_detector

    root, _ = tiny_dataset
    text = perf_detector("antipodal", frames=1, threads=1, data=root)
    assert "detector antipodal" in text and "| detect |" in text and "frames/s" in text
    with pytest.raises(ValueError, match="privileged"):
        perf_detector("oracle", frames=1, data=root)


def test_perf_import_times_each_stage():
    from kgn_bench.perf import perf_import

    report = perf_import(faces=1000, verify=24, hulls=2)
    assert "1000 faces" in report and "wall:" in report
    for stage in ("repair", "decompose", "sample", "verify", "preview"):
        assert f"| {stage} |" in report
