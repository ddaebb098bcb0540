"""VGN training runs of the calibration experiments as closed-loop detectors, before any of them is shipped.

Each name is a detector factory for ``kgn-bench run --detector vgn_runs:NAME`` (``module:attribute``,
docs/detectors.md): the ``vgn`` detector with GIGA's selection on the run folder ``train_vgn_NAME``'s
``final.pt``, named ``vgn_NAME`` in the records, with the weights' SHA-256 as its fingerprint (so a run's
identity changes with the weights)::

    PYTHONPATH=results/calibration kgn-bench run tasks/giga_pile.toml --detector vgn_runs:s600_e90 \\
        --out runs/vgn_runs/giga_pile/s600_e90

Names follow ``vgn_data_volume.sh``: ``s<N>`` the first N scenes of ``data/vgn``, ``_e<E>`` E epochs (without it,
30: the runs made before the schedule grew), then a variant: ``_any`` the rotation trained towards any yaw that
held (``rotation_target = "any_holding"``), ``_noaug`` without the k·90° rotation augmentation. The runs
measured so far: ``s300`` (30 epochs), ``s300_e90``, ``s300_e150``, ``s600_e90`` (shipped as ``vgn``).

``VGN_RUNS`` (default ``runs``) is the folder that holds the ``train_vgn_*`` run folders.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from pathlib import Path

from kgn_bench.detectors.vgn import VGNDetector
from kgn_bench.model.checkpoint import file_sha256

NAME = re.compile(r"s\d+(_e\d+)?(_any|_noaug)?")


def _run(name: str) -> Callable[[], VGNDetector]:
    def make() -> VGNDetector:
        weights = Path(os.environ.get("VGN_RUNS", "runs")) / f"train_vgn_{name}" / "final.pt"
        detector = VGNDetector(weights)
        detector.name = f"vgn_{name}"
        detector.fingerprint = file_sha256(weights)
        return detector

    return make


def __getattr__(name: str) -> Callable[[], VGNDetector]:
    if NAME.fullmatch(name):
        return _run(name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r} (run names: s<N>[_e<E>][_any|_noaug])")
