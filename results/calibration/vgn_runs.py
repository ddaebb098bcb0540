"""VGN training runs of the calibration experiments as closed-loop detectors, before any of them is shipped.

Each attribute is a detector factory for ``kgn-bench run --detector vgn_runs:NAME`` (``module:attribute``,
docs/detectors.md): the ``vgn`` detector with GIGA's selection on the run's ``final.pt``, named ``vgn_NAME`` in
the records, with the weights' SHA-256 as its fingerprint (so a run's identity changes with the weights)::

    PYTHONPATH=results/calibration kgn-bench run tasks/giga_pile.toml --detector vgn_runs:s300 \\
        --out runs/vgn_runs/giga_pile/s300

``VGN_RUNS`` (default ``runs``) is the folder that holds the ``train_vgn_*`` run folders.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from kgn_bench.detectors.vgn import VGNDetector
from kgn_bench.model.checkpoint import file_sha256


def _run(folder: str, name: str) -> Callable[[], VGNDetector]:
    def make() -> VGNDetector:
        weights = Path(os.environ.get("VGN_RUNS", "runs")) / folder / "final.pt"
        detector = VGNDetector(weights)
        detector.name = name
        detector.fingerprint = file_sha256(weights)
        return detector

    return make


s100 = _run("train_vgn_s100", "vgn_s100")
"""The first 100 scenes of ``data/vgn`` (VGN's target: the stored yaw)."""
s300 = _run("train_vgn_s300", "vgn_s300")
"""The first 300 scenes."""
s300_e90 = _run("train_vgn_s300_e90", "vgn_s300_e90")
"""The first 300 scenes, 90 epochs (``s300`` resumed with ``vgn.epochs=90``): what a longer schedule buys."""
s300_e150 = _run("train_vgn_s300_e150", "vgn_s300_e150")
"""The first 300 scenes, 150 epochs (``s300_e90`` resumed with ``vgn.epochs=150``)."""
s600_e90 = _run("train_vgn_s600_e90", "vgn_s600_e90")
"""The first 600 scenes, 90 epochs."""
s300_any = _run("train_vgn_s300_any", "vgn_s300_any")
"""The first 300 scenes, the rotation trained towards any yaw that held (``rotation_target = "any_holding"``)."""
s1000 = _run("train_vgn", "vgn_s1000")
"""All 1000 scenes: ``tasks/vgn_train.toml``'s run, the one ``kgn-bench ship`` makes ``vgn``."""
s300_noaug_e90 = _run("train_vgn_s300_noaug_e90", "vgn_s300_noaug_e90")
"""The first 300 scenes, 90 epochs, without the k·90° rotation augmentation (``augment = false``): GIGA's
camera is one fixed side view in training and test, and GIGA's ``train_vgn.py`` augments only when asked."""
