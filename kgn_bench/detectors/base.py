"""The detector protocol: what a grasp detector sees (``Observation``) and what it returns
(``Candidates``); both types live in ``kgn_bench.types`` and are re-exported here.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from kgn_bench.types import Candidates, DetectorError, Observation

__all__ = ["Candidates", "Detector", "DetectorError", "Observation"]


@runtime_checkable
class Detector(Protocol):
    """A grasp detector. ``privileged`` detectors (the oracle) also get the simulator via ``attach``."""

    name: str
    privileged: bool

    def reset(self, seed: list[int]) -> None:
        """Start a trial: seed any randomness from ``seed`` (the run's seed and the trial index). Before it,
        the harness calls the detector's ``configure(execution)`` if it has one, with the task's
        ``ExecutionConfig`` (e.g. the pre-grasp distance the arm will use)."""

    def detect(self, observation: Observation) -> Candidates:
        """Grasp candidates for one observation (may be empty)."""
