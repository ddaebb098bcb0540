"""The trial adapter of the recordings: what a benchmark trial records (``bench.trial``), turned into calls of a
``viz.recording.Recorder``: the scene's geometry once, the body states every few control ticks, each
observation, each attempt's candidates (world frame) and its outcome line (from its ``AttemptRecord``).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from kgn_bench.bench.records import AttemptRecord
from kgn_bench.viz.recording import Recorder

__all__ = ["NO_RECORDING", "TrialRecording"]


class TrialRecording:
    """What a benchmark trial records, behind three calls: ``observation`` after each capture, ``attempt``
    after each attempt, ``close`` at the end. Opening it logs the scene's geometry and hooks the executor so
    that the state is logged every ``every`` control ticks. ``NO_RECORDING`` does nothing, for trials that
    are not recorded."""

    def __init__(self, path: Path, name: str, model: mujoco.MjModel, data: mujoco.MjData, executor,
                 every: int = 5) -> None:
        self._rec = Recorder(path, name)
        self._rec.log_geometry(model)
        self._rec.log_state(model, data)
        self._data = data
        self._observed_at = float(data.time)
        ticks = iter(range(1, 1 << 62))

        def on_tick() -> None:
            if next(ticks) % every == 0:
                self._rec.log_state(model, data)

        executor.on_tick = on_tick

    def observation(self, rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, camera_pose: np.ndarray) -> None:
        self._observed_at = float(self._data.time)
        self._rec.log_observation(rgb, depth, K, camera_pose, self._observed_at)

    def attempt(self, number: int, attempt: AttemptRecord, poses_world: np.ndarray | None, widths: np.ndarray | None,
                scores: np.ndarray | None, selected: int | None) -> None:
        """The candidates of attempt ``number`` (world frame, if any), logged at the time of the observation
        they were detected in, and its outcome line, logged now (when the attempt has ended)."""
        if poses_world is not None and len(poses_world):
            self._rec.log_candidates(poses_world, widths, scores, selected, self._observed_at)
        outcome = "success" if attempt.success else attempt.reason
        what = f" ({attempt.object})" if attempt.object else ""
        self._rec.log_outcome(f"attempt {number}: {outcome}{what} {attempt.detail}".strip(), self._data.time)

    def close(self) -> None:
        self._rec.close()


class _NoRecording:
    def observation(self, *args, **kwargs) -> None:
        pass

    def attempt(self, *args, **kwargs) -> None:
        pass

    def close(self) -> None:
        pass


NO_RECORDING = _NoRecording()
"""The recording of a trial that is not recorded."""
