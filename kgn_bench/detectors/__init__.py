"""Grasp detectors behind one protocol (``base.Detector``) and a registry by name."""

from __future__ import annotations

from collections.abc import Callable

from .antipodal import AntipodalDetector
from .base import Candidates, Detector, DetectorError, Observation
from .oracle import OracleDetector
from .random import RandomDetector

__all__ = ["DETECTORS", "LEARNED", "Candidates", "Detector", "DetectorError", "Observation", "make_detector"]



def _learned(variant: str) -> Callable[..., Detector]:
    def make(weights=None) -> Detector:
        from .kgn import KGNDetector  # torch is imported only when a learned detector is used

        return KGNDetector(variant, weights)

    return make


LEARNED = ("kgnv2", "kgnv2_sbranch", "kgn", "kgn_depth")
"""Detectors backed by trained weights (one per model variant)."""

DETECTORS: dict[str, Callable[..., Detector]] = {
    "antipodal": AntipodalDetector,
    "oracle": OracleDetector,
    "random": RandomDetector,
    **{v: _learned(v) for v in LEARNED},
}


def make_detector(name: str, weights=None) -> Detector:
    """The detector registered as ``name`` (learned ones with ``weights``: a name under assets/weights or a
    path; default the shipped weights); a clear error listing the known names otherwise."""
    if name not in DETECTORS:
        raise ValueError(f"unknown detector {name!r}; known: {', '.join(sorted(DETECTORS))}")
    if name in LEARNED:
        return DETECTORS[name](weights)
    if weights is not None:
        raise ValueError(f"detector {name!r} takes no weights")
    return DETECTORS[name]()
