"""A kgnv2 spoilt on purpose, for the regression check's test (tests/test_ci_regression.py): every fifth
detection returns no candidate, so about one attempt in five fails. Which detections are blind is decided
by a digest of the depth image, so the same frames go blind in the main process and in every worker."""

from __future__ import annotations

import hashlib

from kgn_bench.detectors import make_detector
from kgn_bench.detectors.base import Candidates, Observation


class EveryFifthBlind:
    name = "kgnv2_every_fifth_blind"
    privileged = False

    def __init__(self) -> None:
        self.inner = make_detector("kgnv2")

    def reset(self, seed: list[int]) -> None:
        self.inner.reset(seed)

    def detect(self, observation: Observation) -> Candidates:
        digest = hashlib.sha256(observation.depth.tobytes()).digest()
        if int.from_bytes(digest[:4], "little") % 5 == 0:
            return Candidates.empty()
        return self.inner.detect(observation)
