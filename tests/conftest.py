"""Shared fixtures: small, seeded, real scenes."""

from __future__ import annotations

# First, before numpy loads: kgn_bench caps every library's CPU kernels at the portable set (kgn_bench.kernels)
# and sets MUJOCO_GL before MuJoCo is imported.
import kgn_bench  # noqa: F401

# isort: split
import numpy as np
import pytest

from kgn_bench.data.generate import GenerateConfig, generate_dataset


@pytest.fixture(scope="session", autouse=True)
def scene_cache(tmp_path_factory):
    """The settled-scene cache (``bench.scene_cache``) of this test session: empty at its start, never the
    user's."""
    import os

    root = tmp_path_factory.mktemp("scene_cache")
    old = os.environ.get("KGN_BENCH_SCENE_CACHE")
    os.environ["KGN_BENCH_SCENE_CACHE"] = str(root)
    yield root
    if old is None:
        os.environ.pop("KGN_BENCH_SCENE_CACHE", None)
    else:
        os.environ["KGN_BENCH_SCENE_CACHE"] = old


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """A 3-scene multi-object dataset with 2 views per scene, generated once per test session."""
    root = tmp_path_factory.mktemp("ps") / "multi"
    config = GenerateConfig(mode="multi", scenes=3, views=2, seed=7)
    generate_dataset(config, root, workers=1, progress=False)
    return root, config


@pytest.fixture(scope="session")
def session_run(tmp_path_factory):
    """``session_run(task, detector, trials=None)``: the run folder of bundled ``tasks/<task>.toml`` (with its
    trial count, or ``trials``) with ``detector`` on the local pool (2 workers), run once per test session
    whoever asks first; readers must not write to it (the CI regression check and ``eval trial`` read the
    same runs)."""
    from pathlib import Path

    from kgn_bench.cli import main

    tasks = Path(__file__).resolve().parents[1] / "tasks"
    runs = {}

    def run(task: str, detector: str, trials: int | None = None):
        key = (task, detector, trials)
        if key not in runs:
            out = tmp_path_factory.mktemp(task) / detector
            argv = ["run", str(tasks / f"{task}.toml"), "--detector", detector, "--workers", "2", "--quiet",
                    "--out", str(out)] + (["--trials", str(trials)] if trials else [])
            assert main(argv) == 0
            runs[key] = out
        return runs[key]

    return run


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


SMALL_NETWORK_KW = dict(stem_channels=8, stage_channels=(8, 16, 16, 32), stage_blocks=(1, 1, 1, 1),
                        neck_channels=16, head_conv=16)


@pytest.fixture
def small_model():
    """``save(path, variant="kgnv2", seed=0, label=None, prepare=None, **extra) -> net``: a seeded small
    network of ``variant`` (``prepare(net)`` may edit it) written as a checkpoint labelled ``label`` (default
    the variant) with ``extra`` entries."""
    import torch

    from kgn_bench.model.checkpoint import model_payload, save_checkpoint
    from kgn_bench.model.network import NetworkConfig, build_network
    from kgn_bench.model.preprocess import InputConfig
    from kgn_bench.model.variants import get_variant

    def save(path, variant="kgnv2", seed=0, label=None, prepare=None, **extra):
        torch.manual_seed(seed)
        config = NetworkConfig(**SMALL_NETWORK_KW)
        net = build_network(get_variant(variant), config)
        if prepare is not None:
            prepare(net)
        save_checkpoint(path, {**model_payload(net, label or variant, config, InputConfig()), **extra})
        return net

    return save


FAST_IMPORT = dict(hulls=2, verify=16)
"""Import settings small enough for tests: at most 2 convex pieces, 16 grasps checked in physics."""


@pytest.fixture(scope="session")
def object_library(tmp_path_factory):
    """A user object library (``$KGN_BENCH_OBJECTS``) holding one imported mesh, ``test_block``: a
    4 × 6 × 10 cm box read from an STL file, imported once per session with ``FAST_IMPORT`` settings."""
    import os

    import trimesh

    from kgn_bench.objects.importer import ImportConfig, import_mesh
    from kgn_bench.shapes.grasp_sampling import SamplingConfig

    root = tmp_path_factory.mktemp("objects")
    old = os.environ.get("KGN_BENCH_OBJECTS")
    os.environ["KGN_BENCH_OBJECTS"] = str(root)
    stl = root.parent / "block.stl"
    trimesh.creation.box((0.04, 0.06, 0.10)).export(stl)
    import_mesh(stl, "test_block", ImportConfig(**FAST_IMPORT, sampling=SamplingConfig(points=200)))
    yield root
    if old is None:
        os.environ.pop("KGN_BENCH_OBJECTS", None)
    else:
        os.environ["KGN_BENCH_OBJECTS"] = old
