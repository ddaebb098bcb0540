"""A fine-tuning run's weights as a closed-loop detector, before they are shipped (issue 44).

``kgn-bench run TASK --detector finetuned:make`` with ``PYTHONPATH=results/mesh_detector`` and
``FINETUNED_WEIGHTS`` the run's ``final.pt``: ``kgnv2_mesh``'s decoding on those weights, named
``kgnv2_mesh_candidate`` in the records, with the weights' SHA-256 as its fingerprint (so a run's identity
changes with the weights).
"""

from __future__ import annotations

import os

from kgn_bench.detectors.kgn import KGNDetector
from kgn_bench.model.checkpoint import file_sha256


def make() -> KGNDetector:
    weights = os.environ["FINETUNED_WEIGHTS"]
    det = KGNDetector("kgnv2_mesh", weights)
    det.name = "kgnv2_mesh_candidate"
    det.fingerprint = file_sha256(weights)
    return det
