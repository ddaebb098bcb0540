"""A kgnv2 spoilt on purpose, for the regression check's test (tests/test_ci_regression.py): every fifth
detection of a trial returns no candidate, so about one attempt in five fails. The count restarts with each
trial (``reset``), so the same detections go blind in the main process and in every worker."""

from __future__ import annotations

from kgn_bench.detectors import make_detector
from kgn_bench.detectors.base import Candidates, Observation


class EveryFifthBlind:
    name = "kgnv2_every_fifth_blind"
    privileged = False

    def __init__(self) -> None:
        self.inner = make_detector("kgnv2")
        self.calls = 0

    def reset(self, seed: list[int]) -> None:
        self.inner.reset(seed)
        self.calls = 0

    def detect(self, observation: Observation) -> Candidates:
        self.calls += 1
        if self.calls % 5 == 0:
            return Candidates.empty()
        return self.inner.detect(observation)
