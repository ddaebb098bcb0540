"""VGN training: the config file, the symmetric rotation loss, the augmentation moving labels with the grid, the
global balance, the gathered loss, and a tiny run that trains, resumes and refuses another dataset."""

import json
import shutil

import numpy as np
import pytest
import torch

from kgn_bench.data.vgn_format import finalize_dataset, read_manifest, write_scene
from kgn_bench.geometry import matrix_from_quat_wxyz, quat_wxyz_from_matrix, rot_x, rot_z
from kgn_bench.model.checkpoint import CheckpointError
from kgn_bench.model.vgn_checkpoint import load_vgn_checkpoint, load_vgn_model
from kgn_bench.model.vgn_network import VGNOutput
from kgn_bench.training.vgn_train import (
    VGNSceneDataset,
    VGNTrainConfig,
    VGNTrainConfigError,
    collate_scenes,
    export_vgn,
    flip_x,
    held_out_metrics,
    holding_rotation_loss,
    load_vgn_train_config,
    negatives_per_scene,
    rotate_scene,
    rotation_loss,
    shift_scene,
    split_scenes,
    train_vgn,
    turned,
    vgn_loss,
)
from kgn_bench.tsdf import VoxelGrid

R = 16
GRID = VoxelGrid(0.12, R, 4.0)


def _random_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def _dataset(folder, seed=0, scenes=4, holds=False):
    """``scenes`` scenes of a 16³ grid: a box on a floor, 12 labelled grasps each (positives on the box); with
    ``holds`` every positive also holds at the next of 6 yaws (a run of two)."""
    rng = np.random.default_rng(seed)
    for s in range(scenes):
        tsdf = np.zeros((R, R, R), np.float32)
        tsdf[:, :, 2:5] = [0.3, 0.5, 0.8]  # the floor's surface band
        lo = rng.integers(3, 9, 3)
        tsdf[lo[0]:lo[0] + 4, lo[1]:lo[1] + 4, 5:9] = 0.4  # a box
        n = 12
        on_top = np.column_stack([lo[:2] + rng.uniform(0, 3, (5, 2)), np.full(5, 9.0)])  # above the box
        voxels = np.concatenate([on_top, rng.uniform(0, R - 1, (n - 5, 3))])
        labels = np.array([1] * 5 + [0] * (n - 5))
        turns = np.zeros((n, 6), bool)
        turns[:, :2] = labels[:, None] == 1
        write_scene(folder, s, tsdf, voxels, _random_quats(rng, n), rng.uniform(2, 8, n), labels,
                    holds=turns if holds else None)
    return finalize_dataset(folder, GRID)


# -- config -----------------------------------------------------------------------------------------------------


def test_config_file(tmp_path):
    path = tmp_path / "vgn.toml"
    path.write_text('[vgn]\ndata = "data/vgn_packed"\nepochs = 12\naugment = false\n')
    cfg = load_vgn_train_config(path)
    assert cfg == VGNTrainConfig(data="data/vgn_packed", epochs=12, augment=False)
    assert (cfg.lr, cfg.batch_size, cfg.held_out, cfg.balance) == (3e-4, 8, 0.1, True)
    for text, match in (('[vgn]\ndata = "d"\nepoch = 3\n', "unknown key 'epoch'"),
                        ('[vgn]\nepochs = 3\n', "data must name the dataset folder"),
                        ('[vgn]\ndata = "d"\nheld_out = 1.5\n', "held_out must lie in"),
                        ('[vgn]\ndata = "d"\nrotation_target = "mean"\n', "rotation_target must be one of"),
                        ('[vgn]\ndata = "d"\n[model]\n', "unknown section")):
        path.write_text(text)
        with pytest.raises(VGNTrainConfigError, match=match) as e:
            load_vgn_train_config(path)
        assert str(path) in str(e.value) and "\n" not in str(e.value)


# -- rotation loss --------------------------------------------------------------------------------------------


def test_the_rotation_loss_is_zero_for_both_forms_of_a_grasp(rng):
    q = _random_quats(rng, 50)
    flipped = np.stack([quat_wxyz_from_matrix(matrix_from_quat_wxyz(a) @ rot_x(np.pi)) for a in q])
    t = torch.tensor(q, dtype=torch.float64)
    for pred in (q, flipped, -q, -flipped):
        torch.testing.assert_close(rotation_loss(torch.tensor(pred), t), torch.zeros(50, dtype=torch.float64))
    torch.testing.assert_close(flip_x(t), torch.tensor(flipped) * torch.sign(flip_x(t)[:, :1] * torch.tensor(
        flipped[:, :1])))  # flip_x is q · R_x(π) up to the sign of the quaternion
    # a quarter turn about the approach axis is a different grasp: 1 − cos(π/4)
    quarter = np.stack([quat_wxyz_from_matrix(matrix_from_quat_wxyz(a) @ rot_x(np.pi / 2)) for a in q])
    torch.testing.assert_close(rotation_loss(torch.tensor(quarter), t),
                               torch.full((50,), 1 - np.cos(np.pi / 4), dtype=torch.float64))


def test_turned_targets_are_turns_about_the_approach(rng):
    q = _random_quats(rng, 5)
    got = turned(torch.tensor(q), 6).numpy()
    assert got.shape == (5, 6, 4)
    for n in range(5):
        for j in range(6):
            np.testing.assert_allclose(matrix_from_quat_wxyz(got[n, j]),
                                       matrix_from_quat_wxyz(q[n]) @ rot_x(j * np.pi / 6), atol=1e-9)


def test_any_holding_yaw_is_a_right_answer(rng):
    """The set target costs nothing at any holding turn (in either finger order), the turn's own cost at the
    others, and falls back to the stored yaw where nothing held."""
    q = torch.tensor(_random_quats(rng, 3))
    holds = torch.tensor([[True, False, True, False, False, False], [True] * 6, [False] * 6])
    turns = turned(q, 6)
    for j in range(6):
        pred = turns[:, j]
        loss = holding_rotation_loss(pred, q, holds)
        assert (float(loss[0]) < 1e-9) == (j in (0, 2)) and float(loss[1]) < 1e-9
        torch.testing.assert_close(loss[2], rotation_loss(pred, q)[2])
        torch.testing.assert_close(holding_rotation_loss(flip_x(pred), q, holds), loss)
    # a prediction 30° off every holding turn costs 1 − cos(15°): the nearest one counts
    torch.testing.assert_close(holding_rotation_loss(turns[:1, 1], q[:1], holds[:1]),
                               torch.tensor([1 - np.cos(np.pi / 12)], dtype=q.dtype))


# -- augmentation -------------------------------------------------------------------------------------------


@pytest.mark.parametrize("k", [0, 1, 2, 3])
def test_rotation_moves_labels_with_the_grid(k, rng):
    tsdf = np.zeros((R, R, R), np.float32)
    tsdf[3, 11, 7] = 1.0  # one occupied voxel, a label on it and one 0.4 voxel beside it
    voxels = np.array([[3.0, 11.0, 7.0], [3.4, 11.0, 7.0]], np.float32)
    quats = _random_quats(rng, 2).astype(np.float32)
    out, moved, turned = rotate_scene(tsdf, voxels, quats, k)
    assert out.shape == tsdf.shape and out.sum() == 1.0
    np.testing.assert_allclose(moved[0], np.argwhere(out == 1.0)[0], atol=1e-5)
    # in world terms: the grid and the labels turned by the same R_z(k·90°) about the grid centre
    centre = np.array([(R - 1) / 2, (R - 1) / 2, 0.0])
    Rz = rot_z(k * np.pi / 2)
    np.testing.assert_allclose(moved, (voxels - centre) @ Rz.T + centre, atol=1e-5)
    for a, b in zip(quats, turned, strict=True):
        np.testing.assert_allclose(matrix_from_quat_wxyz(b), Rz @ matrix_from_quat_wxyz(a), atol=1e-6)


def test_vertical_shift_moves_labels_and_drops_those_that_leave(rng):
    tsdf = np.zeros((R, R, R), np.float32)
    tsdf[5, 6, 2] = 1.0
    voxels = np.array([[5.0, 6.0, 2.0], [1.0, 1.0, 14.0]], np.float32)
    out, moved, inside = shift_scene(tsdf, voxels, 3)
    assert np.argwhere(out == 1.0).tolist() == [moved[0].astype(int).tolist()] == [[5, 6, 5]]
    assert inside.tolist() == [True, False]
    out, moved, inside = shift_scene(tsdf, voxels, -3)
    assert out.sum() == 0 and inside.tolist() == [False, True]


def test_the_dataset_keeps_each_label_on_its_voxel(tmp_path, rng):
    """Through the training dataset (augmented, several epochs): the label stays on the one occupied voxel."""
    tsdf = np.zeros((R, R, R), np.float32)
    tsdf[2, 12, 6] = 1.0
    write_scene(tmp_path, 0, tsdf, [[2.2, 11.9, 6.1]], _random_quats(rng, 1), [4.0], [1])
    m = finalize_dataset(tmp_path, GRID)
    ds = VGNSceneDataset(tmp_path, list(m.scenes), seed=3, augment=True, z_shift=2)
    seen = set()
    for epoch in range(12):
        ds.set_epoch(epoch)
        item = ds[0]
        i, j, k = item["index"][0].tolist()
        assert item["tsdf"][0, i, j, k] == 1.0
        seen.add((i, j))
    assert len(seen) == 4  # every quarter turn occurred


def test_the_dataset_carries_every_yaws_outcome_through_augmentation(tmp_path):
    m = _dataset(tmp_path, scenes=2, holds=True)
    ds = VGNSceneDataset(tmp_path, list(m.scenes), seed=0, augment=True, z_shift=3)
    for epoch in range(4):
        ds.set_epoch(epoch)
        item = ds[0]
        assert item["holds"].shape == (len(item["label"]), 6)
        assert torch.equal(item["holds"][:, 0], item["label"] > 0.5) and torch.equal(item["holds"][:, 0],
                                                                                     item["holds"][:, 1])
    batch = collate_scenes([ds[0], ds[1]])
    assert batch["holds"].shape == (len(batch["label"]), 6)
    plain = _dataset(tmp_path / "plain", scenes=1)
    assert "holds" not in VGNSceneDataset(tmp_path / "plain", list(plain.scenes), seed=0)[0]


# -- balance and loss ----------------------------------------------------------------------------------------


def test_balance_keeps_as_many_negatives_as_positives(tmp_path):
    m = _dataset(tmp_path)
    scenes = list(m.scenes)
    keep = negatives_per_scene(scenes, np.random.default_rng(0))
    assert keep.sum() == m.positives == 20 and np.all(keep <= [s.negatives for s in scenes])
    ds = VGNSceneDataset(tmp_path, scenes, seed=0)
    draws = []
    for epoch in range(3):
        ds.set_epoch(epoch)
        assert ds.labels() == (20, 20)
        assert sum(len(ds[n]["label"]) for n in range(len(ds))) == 40
        draws.append(tuple(ds.keep_negatives))
    assert len(set(draws)) > 1  # redrawn each epoch
    unbalanced = VGNSceneDataset(tmp_path, scenes, seed=0, balance=False)
    assert unbalanced.labels() == (20, 28)


def test_the_loss_reads_each_scene_at_its_own_labels():
    """A prediction equal to the targets at the labelled voxels (and wrong elsewhere) costs nothing."""
    items = []
    for index, label in (([[1, 2, 3], [4, 5, 6]], [1.0, 0.0]), ([[1, 2, 3]], [0.0])):
        n = len(label)
        items.append({"tsdf": torch.zeros(1, 8, 8, 8), "index": torch.tensor(index), "label": torch.tensor(label),
                      "quat": torch.nn.functional.normalize(torch.arange(4 * n, dtype=torch.float32).reshape(n, 4)
                                                            + 1, dim=1),
                      "width": torch.tensor([3.0] * n)})
    batch = collate_scenes(items)
    assert batch["tsdf"].shape == (2, 1, 8, 8, 8) and batch["index"].tolist() == [[0, 1, 2, 3], [0, 4, 5, 6],
                                                                                 [1, 1, 2, 3]]
    quality = torch.full((2, 1, 8, 8, 8), 0.5)
    rotation = torch.zeros(2, 4, 8, 8, 8)
    rotation[:, 1] = 1.0
    width = torch.zeros(2, 1, 8, 8, 8)
    for (b, i, j, k), label, q, w in zip(batch["index"].tolist(), batch["label"], batch["quat"], batch["width"],
                                         strict=True):
        quality[b, 0, i, j, k] = label
        rotation[b, :, i, j, k] = q
        width[b, 0, i, j, k] = w
    loss, parts = vgn_loss(VGNOutput(quality, rotation, width), batch)
    assert float(loss) < 1e-5 and parts["labels"] == 3
    width[0, 0, 1, 2, 3] += 2.0  # the positive's width off by 2 voxels: 0.01 · 4 / 3 labels
    loss, _ = vgn_loss(VGNOutput(quality, rotation, width), batch)
    assert float(loss) == pytest.approx(0.04 / 3, abs=1e-5)


def test_split_is_seeded_and_disjoint(tmp_path):
    m = _dataset(tmp_path, scenes=10)
    train, held = split_scenes(m, 0.2, seed=5)
    assert len(held) == 2 and len(train) == 8 and not {s.id for s in train} & {s.id for s in held}
    assert split_scenes(m, 0.2, seed=5) == (train, held)
    assert len(split_scenes(m, 0.1, seed=5, max_scenes=4)[1]) == 1


# -- a run ---------------------------------------------------------------------------------------------------------


def _history(run):
    return [json.loads(line) for line in (run / "history.jsonl").read_text().splitlines()]


def test_trains_resumes_and_refuses_another_dataset(tmp_path):
    data = tmp_path / "data"
    _dataset(data)
    cfg = VGNTrainConfig(data=str(data), epochs=2, batch_size=2, held_out=0.25, seed=1)
    run = tmp_path / "run"
    train_vgn(cfg, run, threads=1, device="cpu")
    rows = _history(run)
    assert [r["epoch"] for r in rows] == [1, 2]
    for r in rows:
        assert np.isfinite(r["loss"]) and np.isfinite(r["held_out_loss"]) and 0 <= r["accuracy"] <= 1
        assert r["labels"] == 2 * sum(s.positives for s in split_scenes(read_manifest(data), 0.25, 1)[0])
    ckpt = load_vgn_checkpoint(run / "last.pt")
    assert ckpt["epoch"] == 2 and "optimizer" in ckpt and ckpt["dataset"]["sha256"] == read_manifest(data).sha256
    assert ckpt["dataset"]["train_scenes"] == 3 and ckpt["dataset"]["held_out_scenes"] == 1

    final = train_vgn(VGNTrainConfig(**{**cfg.to_dict(), "epochs": 3}), run, threads=1, device="cpu")
    rows3 = _history(run)
    assert [r["epoch"] for r in rows3] == [1, 2, 3] and rows3[:2] == rows
    assert load_vgn_checkpoint(final)["epoch"] == 3 and "optimizer" not in load_vgn_checkpoint(final)
    # resuming gives the weights of an uninterrupted run
    straight = tmp_path / "straight"
    train_vgn(VGNTrainConfig(**{**cfg.to_dict(), "epochs": 3}), straight, threads=1, device="cpu")
    a, b = load_vgn_model(run / "final.pt").net.state_dict(), load_vgn_model(straight / "final.pt").net.state_dict()
    for key in a:
        torch.testing.assert_close(a[key], b[key])

    other = tmp_path / "other"
    _dataset(other, seed=9)
    with pytest.raises(CheckpointError, match="another dataset"):
        train_vgn(VGNTrainConfig(**{**cfg.to_dict(), "data": str(other), "epochs": 4}), run, device="cpu")
    with pytest.raises(CheckpointError, match="other settings"):
        train_vgn(VGNTrainConfig(**{**cfg.to_dict(), "lr": 1e-3, "epochs": 4}), run, device="cpu")

    moved = tmp_path / "moved"
    shutil.copytree(data, moved)  # the same dataset in another folder resumes
    train_vgn(VGNTrainConfig(**{**cfg.to_dict(), "data": str(moved), "epochs": 4}), run, device="cpu")
    assert [r["epoch"] for r in _history(run)] == [1, 2, 3, 4]

    weights, card = export_vgn(run, "vgn_tiny", tmp_path / "ship")
    assert load_vgn_model(weights).grid == GRID and "| sha256 |" in card.read_text()


def test_a_run_on_a_prefix_resumes_after_the_dataset_grows(tmp_path):
    """A run on the first 3 scenes is identified by those scenes: it resumes once a fifth scene is added and the
    manifest written again, and refuses when one of its own scenes changed."""
    data = tmp_path / "data"
    small = _dataset(data, scenes=4)
    cfg = VGNTrainConfig(data=str(data), epochs=1, batch_size=2, held_out=0.34, seed=1, max_scenes=3)
    run = tmp_path / "run"
    train_vgn(cfg, run, threads=1, device="cpu")
    grown = _dataset(data, scenes=5)  # the same first four scenes, one more
    assert grown.sha256 != small.sha256 and grown.prefix_sha256(3) == small.prefix_sha256(3)
    assert small.prefix_sha256(0) == small.prefix_sha256(9) == small.sha256
    train_vgn(VGNTrainConfig(**{**cfg.to_dict(), "epochs": 2}), run, threads=1, device="cpu")
    assert [r["epoch"] for r in _history(run)] == [1, 2]
    _dataset(data, scenes=5, seed=9)  # other scenes under the same names
    with pytest.raises(CheckpointError, match="another dataset"):
        train_vgn(VGNTrainConfig(**{**cfg.to_dict(), "epochs": 3}), run, threads=1, device="cpu")


def test_the_holding_set_target_trains_and_reports_hits(tmp_path):
    data = tmp_path / "data"
    _dataset(data, holds=True)
    cfg = VGNTrainConfig(data=str(data), epochs=1, batch_size=2, held_out=0.25, seed=1, rotation_target="any_holding")
    train_vgn(cfg, tmp_path / "run", threads=1, device="cpu")
    row = _history(tmp_path / "run")[0]
    assert np.isfinite(row["rotation"]) and 0.0 <= row["rotation_hit"] <= 1.0
    # a network that outputs a holding turn at every voxel hits every positive; one a quarter turn off, none
    m = read_manifest(data)
    ds = VGNSceneDataset(data, list(m.scenes), seed=0)
    batch = collate_scenes([ds[n] for n in range(len(ds))])
    _, first = np.unique(batch["index"].numpy(), axis=0, return_index=True)  # one label a voxel
    batch = {key: (value if key == "tsdf" else value[torch.from_numpy(np.sort(first))]) for key, value in batch.items()}
    assert int(batch["label"].sum()) > 5

    class Constant(torch.nn.Module):
        def __init__(self, q):
            super().__init__()
            self.q = q

        def forward(self, tsdf):
            b, _, r = tsdf.shape[:3]
            out = VGNOutput(torch.full((b, 1, r, r, r), 0.9), torch.zeros(b, 4, r, r, r),
                            torch.zeros(b, 1, r, r, r))
            bb, i, j, k = batch["index"].unbind(1)
            out.rotation[bb, :, i, j, k] = self.q
            return out

    loader = [batch]
    assert held_out_metrics(Constant(turned(batch["quat"], 6)[:, 1]), loader, torch.device("cpu"),
                            "any_holding")["rotation_hit"] == 1.0
    assert held_out_metrics(Constant(turned(batch["quat"], 2)[:, 1]), loader, torch.device("cpu"),
                            "any_holding")["rotation_hit"] == 0.0  # 90°: 60° past the run of 0° and 30°
    # the set target needs data that stores every yaw's outcome
    from kgn_bench.data.format import DatasetError

    _dataset(tmp_path / "plain")
    with pytest.raises(DatasetError, match="needs every yaw's outcome"):
        train_vgn(VGNTrainConfig(**{**cfg.to_dict(), "data": str(tmp_path / "plain")}), tmp_path / "run2",
                  threads=1, device="cpu")


def test_a_dataset_of_test_objects_is_never_trained_on(tmp_path):
    from kgn_bench.data.format import DatasetError

    data = tmp_path / "data"
    _dataset(data, scenes=2)
    finalize_dataset(data, GRID, settings={"objects": ["cuboid", "pb_mug"]})
    with pytest.raises(DatasetError, match=r"real test objects \(pb_mug\)"):
        train_vgn(VGNTrainConfig(data=str(data), epochs=1, batch_size=2), tmp_path / "run", threads=1, device="cpu")
    assert not (tmp_path / "run" / "last.pt").exists()
