"""The label-free check of predictions: the real detector's top grasps go through real physics, and grasps
that are plainly wrong (moved 15 cm back along their approach, closing on air) all fail."""

from __future__ import annotations

import numpy as np

from kgn_bench.detectors.kgn import KGNDetector
from kgn_bench.eval.physics_check import physics_success, to_markdown
from kgn_bench.geometry import make_pose
from kgn_bench.types import Candidates


def test_top_predictions_of_kgnv2_mostly_hold(tiny_dataset):
    root, _ = tiny_dataset
    counts = physics_success(KGNDetector("kgnv2"), root, views=2, top_k=3, progress=False)
    assert counts["all"]["checked"] == 6
    assert counts["all"]["held"] >= 3  # the shipped model's best grasps on primitives are good grasps
    assert sum(c["checked"] for name, c in counts.items() if name != "all") == 6
    assert "| all | 6 |" in to_markdown(counts, "kgnv2")


def test_grasps_off_the_object_fail(tiny_dataset):
    root, _ = tiny_dataset
    detector = KGNDetector("kgnv2")

    def backed_off(observation):
        c = detector.detect(observation)
        back = c.poses @ make_pose(t=np.array([-0.15, 0.0, 0.0]))
        return Candidates(back, c.widths, c.confidences, c.reprojection_errors)

    counts = physics_success(backed_off, root, views=2, top_k=3, progress=False)
    assert counts["all"]["checked"] == 6 and counts["all"]["held"] == 0 and counts["all"]["labelled"] == 0


def test_cli_writes_the_table(tiny_dataset, tmp_path):
    from kgn_bench.cli import main

    root, _ = tiny_dataset
    out = tmp_path / "new" / "physics"
    assert main(["eval", "physics", "--weights", "kgnv2", "--data", str(root), "--views", "1", "--top", "2",
                 "--quiet", "--out", str(out)]) == 0
    assert "| all | 2 |" in (out / "physics.md").read_text()
