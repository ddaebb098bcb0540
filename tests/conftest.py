"""Shared fixtures: small, seeded, real scenes."""

from __future__ import annotations

import numpy as np
import pytest

import kgn_bench  # noqa: F401  (sets MUJOCO_GL before MuJoCo is imported)
from kgn_bench.data.generate import GenerateConfig, generate_dataset


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """A 3-scene multi-object dataset with 2 views per scene, generated once per test session."""
    root = tmp_path_factory.mktemp("ps") / "multi"
    config = GenerateConfig(mode="multi", scenes=3, views=2, seed=7)
    generate_dataset(config, root, workers=1, progress=False)
    return root, config


@pytest.fixture
def rng():
    return np.random.default_rng(12345)
