"""Setting sweeps on real trials: one run folder per value, the sweep table, noise reaching the detector."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from kgn_bench.bench.sweep import run_sweep
from kgn_bench.bench.trial import run_trial
from kgn_bench.config import ConfigError, apply_override, load_task
from kgn_bench.detectors.base import Candidates
from kgn_bench.sim.control import IK

TASKS = Path(__file__).resolve().parents[1] / "tasks"


@pytest.fixture(scope="module")
def task():
    """One single-object sphere trial."""
    return replace(load_task(TASKS / "ci_oracle.toml"), objects=("sphere",), trials=1)


class _Spy:
    """A detector that remembers what it saw and proposes nothing."""

    name = "spy"
    privileged = False

    def __init__(self) -> None:
        self.depths: list[np.ndarray] = []

    def reset(self, seed: list[int]) -> None:
        pass

    def detect(self, observation) -> Candidates:
        self.depths.append(observation.depth.copy())
        return Candidates.empty()


def test_depth_noise_reaches_the_detector_and_is_seeded_per_trial(task):
    ik = IK()
    seen = {}
    for strength in (0.0, 1.0, 1.0):
        spy = _Spy()
        record = run_trial(apply_override(task, "camera.depth_noise", str(strength)), 0, spy, ik)
        assert record.attempts[0].reason == "no_candidate"
        seen.setdefault(strength, []).append(spy.depths[0])
    clean, (noisy, again) = seen[0.0][0], seen[1.0]
    np.testing.assert_array_equal(noisy, again)  # same task, seed and trial: same noise
    both = (clean > 0) & (noisy > 0)
    assert (noisy == 0).mean() > (clean == 0).mean() + 0.02  # shadows, left band, edge dropouts
    assert 0.5e-3 < np.sqrt(np.mean((noisy[both] - clean[both]) ** 2)) < 5e-3  # ~2-3 mm at 0.6-1 m


def test_sweep_runs_each_value_on_the_same_scene_and_tabulates_them(task, tmp_path):
    points = run_sweep(task, "oracle", "camera.depth_noise", ["0", "1"], tmp_path, progress=False)
    assert [p.value for p in points] == ["0", "1"]
    for p in points:
        run = json.loads((p.out / "run.json").read_text())
        assert run["config"]["camera"]["depth_noise"] == float(p.value)
        assert p.summary["trials"] == 1
    objects = [json.loads((p.out / "trials.jsonl").read_text().splitlines()[0])["objects"] for p in points]
    assert objects[0] == objects[1] == ["sphere"]
    payload = json.loads((tmp_path / "sweep.json").read_text())
    assert payload["key"] == "camera.depth_noise" and len(payload["points"]) == 2
    table = (tmp_path / "sweep.md").read_text()
    assert "| camera.depth_noise | success" in table and "\n| 0 | " in table and "\n| 1 | " in table


def test_a_bad_value_stops_the_sweep_before_any_trial(task, tmp_path):
    with pytest.raises(ConfigError, match="depth_noise must be in"):
        run_sweep(task, "oracle", "camera.depth_noise", ["0", "20"], tmp_path, progress=False)
    assert not any(tmp_path.iterdir())


def test_a_viewpoint_study_puts_detectors_side_by_side_with_a_plot(task, tmp_path):
    import cv2

    from kgn_bench.bench.sweep import run_detector_sweep

    series = run_detector_sweep(task, ["oracle", "random"], "camera.elevation_deg", ["45", "90"], tmp_path,
                                progress=False)
    assert list(series) == ["oracle", "random"] and all(len(points) == 2 for points in series.values())
    for det in series:
        run = json.loads((tmp_path / det / "camera.elevation_deg=90" / "run.json").read_text())
        assert run["detector"] == det and run["config"]["camera"]["elevation_deg"] == 90.0
        assert (tmp_path / det / "sweep.png").is_file()
    table = (tmp_path / "sweep.md").read_text()
    assert "| camera.elevation_deg | oracle success | random success |" in table and "\n| 45 | " in table
    image = cv2.imread(str(tmp_path / "sweep.png"))
    assert image is not None and image.shape[1] > 300
    payload = json.loads((tmp_path / "sweep.json").read_text())
    assert set(payload["detectors"]) == {"oracle", "random"}
    with pytest.raises(ConfigError, match="elevation_deg must lie in"):
        run_detector_sweep(task, ["oracle"], "camera.elevation_deg", ["95"], tmp_path / "bad", progress=False)
    assert not (tmp_path / "bad").exists()
