from kgn_bench.perf import perf_data


def test_perf_data_reports_views_per_second_and_the_split():
    report = perf_data(scenes=1, workers=1, mode="single", views=1)
    assert "views/s" in report
    for stage in ("settle", "annotate", "render", "write"):
        assert f"| {stage} |" in report
