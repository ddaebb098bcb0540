"""scripts/train_gpu.sh: data, training and shipping from nothing, run here on the CPU with a tiny setting."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]


def test_train_gpu_script_generates_trains_and_ships(tmp_path):
    env = {**os.environ, "KGN": f"{sys.executable} -m kgn_bench.cli", "DEVICE": "cpu", "SCENES": "4", "VIEWS": "2",
           "WORKERS": "1", "DATA": str(tmp_path / "data"), "RUN": str(tmp_path / "run"), "OUT": str(tmp_path / "w")}
    done = subprocess.run(
        ["bash", str(ROOT / "scripts" / "train_gpu.sh"), str(ROOT / "tasks" / "train_kgnv2_multi_s2.toml"), "tiny",
         "--set", "train.epochs=1", "--set", "train.limit=4", "--set", "train.batch_size=2", "--set",
         "train.eval_views=2", "--set", "train.workers=0"],
        env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "data: " in done.stdout and "wrote " in done.stdout
    ckpt = torch.load(tmp_path / "w" / "tiny.pt", map_location="cpu", weights_only=False)
    assert ckpt["network"]["output_stride"] == 2 and ckpt["train"]["train"]["epochs"] == 1
    assert "output_stride" in (tmp_path / "w" / "tiny.md").read_text()


def test_train_gpu_script_takes_vgn_config(tmp_path):
    env = {**os.environ, "KGN": f"{sys.executable} -m kgn_bench.cli", "DEVICE": "cpu", "SCENES": "2",
           "OBJECTS": "cuboid cylinder", "WORKERS": "1", "DATA": str(tmp_path / "data"), "RUN": str(tmp_path / "run"),
           "OUT": str(tmp_path / "w")}
    done = subprocess.run(
        ["bash", str(ROOT / "scripts" / "train_gpu.sh"), str(ROOT / "tasks" / "vgn_train.toml"), "tiny_vgn",
         "--set", "vgn.epochs=1", "--set", "vgn.workers=0"],
        env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "data: " in done.stdout and "(VGN)" in done.stdout and "wrote " in done.stdout
    assert sorted(p.name for p in (tmp_path / "data" / "scenes").iterdir()) == ["000000.npz", "000001.npz"]
    ckpt = torch.load(tmp_path / "w" / "tiny_vgn.pt", map_location="cpu", weights_only=False)
    assert ckpt["train"]["epochs"] == 1 and ckpt["train"]["data"] == str(tmp_path / "data")
    assert "VGN" in (tmp_path / "w" / "tiny_vgn.md").read_text()
