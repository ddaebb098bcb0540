"""The antipodal detector's settings: one frozen dataclass whose defaults are the detector's, and which the
detector really uses."""

import dataclasses
import inspect

import numpy as np
import pytest

from kgn_bench.detectors import make_detector
from kgn_bench.detectors.antipodal import AntipodalDetector
from kgn_bench.detectors.antipodal_config import AntipodalConfig
from kgn_bench.gripper import GRIPPER


def test_defaults_are_the_registered_detectors_settings():
    cfg = AntipodalConfig()
    assert (cfg.stride, cfg.seeds, cfg.approaches, cfg.closings, cfg.neighbours) == (2, 160, 5, 6, 900)
    assert (cfg.radius, cfg.min_height, cfg.collision_height) == (0.2, 0.005, 0.002)
    assert cfg.depth == GRIPPER.finger_length - 0.02
    assert (cfg.min_depth, cfg.margin, cfg.min_width) == (0.004, 0.008, 0.02)
    assert (cfg.table_clearance, cfg.push) == (0.004, 0.01)
    assert (cfg.cone_deg, cfg.min_enclosed, cfg.top, cfg.chunk) == (20.0, 6, 300, 384)
    assert make_detector("antipodal").config == cfg
    assert len(dataclasses.fields(cfg)) == 18


def test_frozen_and_replaceable():
    cfg = AntipodalConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.seeds = 3  # type: ignore[misc]
    assert dataclasses.replace(cfg, seeds=3).seeds == 3 and cfg.seeds == 160


def test_every_field_is_documented():
    source = inspect.getsource(AntipodalConfig)
    for field in dataclasses.fields(AntipodalConfig):
        line = next(ln for ln in source.splitlines() if ln.strip().startswith(f"{field.name}:"))
        after = source.split(line, 1)[1].lstrip()
        assert after.startswith('"""'), f"{field.name} has no docstring"


def test_the_detector_takes_its_settings_from_the_config():
    det = AntipodalDetector(AntipodalConfig(cone_deg=30.0, top=5))
    assert det.config.top == 5 and det.cone == np.deg2rad(30.0)
    assert AntipodalDetector().config == AntipodalConfig()
