"""Grasp detectors behind one protocol (``base.Detector``) and a registry by name."""

from __future__ import annotations

from collections.abc import Callable

from .base import Candidates, Detector, DetectorError, Observation
from .oracle import OracleDetector
from .random import RandomDetector

__all__ = ["DETECTORS", "Candidates", "Detector", "DetectorError", "Observation", "make_detector"]

DETECTORS: dict[str, Callable[[], Detector]] = {
    "oracle": OracleDetector,
    "random": RandomDetector,
}


def make_detector(name: str) -> Detector:
    """The detector registered as ``name``; a clear error listing the known names otherwise."""
    if name not in DETECTORS:
        raise ValueError(f"unknown detector {name!r}; known: {', '.join(sorted(DETECTORS))}")
    return DETECTORS[name]()
