"""VGN weights files: round trip, export with a model card whose SHA-256 guards the file, one-line refusals."""

import pytest
import torch

from kgn_bench.model.checkpoint import CheckpointError, file_sha256
from kgn_bench.model.vgn_checkpoint import (
    VGN_FORMAT,
    export_vgn_weights,
    load_vgn_checkpoint,
    load_vgn_model,
    save_vgn_checkpoint,
    vgn_model_card,
    vgn_payload,
)
from kgn_bench.model.vgn_network import VGNNet
from kgn_bench.tsdf import VoxelGrid

GRID = VoxelGrid()


def _run_checkpoint(path):
    torch.manual_seed(1)
    net = VGNNet()
    history = [{"epoch": 1, "loss": 0.9, "held_out_loss": 0.8, "accuracy": 0.6, "precision": 0.5, "recall": 0.7,
                "seconds": 120.0}]
    save_vgn_checkpoint(path, {**vgn_payload(net, GRID), "train": {"batch_size": 8, "lr": 3e-4, "augment": True,
                                                                    "seed": 0},
                               "dataset": {"path": "data/vgn", "scenes": 10, "grasps": 900, "positives": 400,
                                           "sha256": "ab" * 32}, "epoch": 1, "history": history,
                               "optimizer": {"state": {}, "param_groups": []}, "torch_rng": torch.get_rng_state(),
                               "machine": "test machine"})
    return net


def test_round_trip(tmp_path):
    net = _run_checkpoint(tmp_path / "last.pt")
    loaded = load_vgn_model(tmp_path / "last.pt")
    assert loaded.grid == GRID and not loaded.net.training
    for k, v in net.state_dict().items():
        torch.testing.assert_close(loaded.net.state_dict()[k], v)
    assert loaded.meta["format"] == VGN_FORMAT and loaded.meta["parameters"] == 313_238
    assert "optimizer" not in loaded.meta


def test_export_writes_weights_and_a_card_that_guards_them(tmp_path):
    _run_checkpoint(tmp_path / "last.pt")
    weights, card = export_vgn_weights(tmp_path / "last.pt", "vgn", tmp_path / "ship")
    assert weights.stat().st_size < 16e6
    data = load_vgn_checkpoint(weights)
    assert "optimizer" not in data and "torch_rng" not in data
    text = card.read_text()
    assert f"| sha256 | `{file_sha256(weights)}` |" in text
    for fact in ("10 scenes", "900 labelled grasps", "accuracy 60.0 %", "recall 70.0 %", "2 min", "test machine"):
        assert fact in text, fact
    weights.write_bytes(weights.read_bytes() + b"x")  # the file no longer matches its card
    with pytest.raises(CheckpointError, match="SHA-256 differs from its model card"):
        load_vgn_model(weights)


def test_weights_of_another_shape_are_refused(tmp_path):
    payload = vgn_payload(VGNNet(), GRID)
    payload["model"]["quality.weight"] = torch.zeros(2, 16, 5, 5, 5)
    save_vgn_checkpoint(tmp_path / "bad.pt", payload)
    with pytest.raises(CheckpointError, match="weights do not fit VGN") as e:
        load_vgn_model(tmp_path / "bad.pt")
    assert "\n" not in str(e.value)


def test_other_versions_and_grids_are_refused(tmp_path):
    path = tmp_path / "w.pt"
    torch.save({"format": VGN_FORMAT, "version": 99, "model": {}, "grid": {}}, path)
    with pytest.raises(CheckpointError, match="version 99"):
        load_vgn_checkpoint(path)
    save_vgn_checkpoint(path, {**vgn_payload(VGNNet(), GRID), "grid": {"size": 0.3, "resolution": 36,
                                                                       "truncation_voxels": 4}})
    with pytest.raises(CheckpointError, match="divisible by 8"):
        load_vgn_model(path)


def test_a_card_without_held_out_metrics():
    card = vgn_model_card({"history": [{"epoch": 1, "loss": 0.5, "held_out_loss": None, "accuracy": None}]}, "x", 1000)
    assert "held-out n/a" in card and "accuracy n/a" in card and "1: 0.500 / n/a" in card


def test_a_card_states_the_datas_generation_cost():
    data = {"dataset": {"generation_seconds": 9000.0, "objects": 303, "labels": "physics-floating-panda-v3"},
            "history": []}
    card = vgn_model_card(data, "x", 1000)
    assert "| data generation | 2.5 core-hours" in card and "303 object types" in card
    assert "physics-floating-panda-v3" in card
    assert "data generation" not in vgn_model_card({"history": []}, "x", 1000)


def test_a_card_states_the_rotation_hit_rate_where_measured():
    row = {"epoch": 2, "loss": 0.5, "held_out_loss": 0.6, "accuracy": 0.8, "precision": 0.7, "recall": 0.6}
    assert "rotation within 15°" not in vgn_model_card({"history": [row]}, "x", 1000)
    card = vgn_model_card({"history": [{**row, "rotation_hit": 0.412}]}, "x", 1000)
    assert "recall 60.0 %, rotation within 15° of a holding one 41.2 % |" in card
    assert "![training curves](x_training.png)" in card
