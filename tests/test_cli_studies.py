"""kgn-bench study (kgn_bench.cli.studies): pnp-noise writes its table and figure."""

from kgn_bench.cli import main


def test_study_pnp_noise_writes_the_csv_and_the_figure(tmp_path, capsys):
    import cv2

    assert main(["study", "pnp-noise", "--samples", "50", "--sigmas", "1", "--out", str(tmp_path / "fig2")]) == 0
    lines = (tmp_path / "fig2.csv").read_text().splitlines()
    assert len(lines) == 1 + 2 * 13  # header + 2 boxes × 13 distances
    img = cv2.imread(str(tmp_path / "fig2.png"))
    assert img is not None and img.shape[1] > 1000
    assert "scale_normalized" in capsys.readouterr().out
