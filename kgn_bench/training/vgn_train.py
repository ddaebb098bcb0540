"""Training VGN with full-volume supervision: one forward pass per scene, the loss at every labelled voxel.

**Samples.** A sample is one scene of a ``data.vgn_format`` dataset: the network input (R³) and its labelled
grasps (voxel coordinates, quaternion of ``R_grid_grasp`` (w, x, y, z), width in voxels, label). VGN and GIGA
instead make one sample per grasp and read the network at that grasp's voxel only; gathering all of a scene's
labels from one forward pass gives the same per-grasp loss for ~100× fewer forward passes.

**Balance** (``balance = true``, the default). VGN's cleaning drops randomly chosen negatives until the whole
dataset has as many negatives as positives. Here the same global balance is drawn afresh every epoch: the
number of negatives each scene keeps is one multivariate hypergeometric draw of ``min(P, N)`` out of all ``N``
negatives (so exactly as many negatives as positives over the split, spread over the scenes in proportion to
their negatives, scenes without positives included), and which negatives a scene keeps is a uniform draw. The
held-out split is balanced once (the draw of "epoch 0"), so its metrics compare across epochs. Every draw comes
from ``numpy.random.default_rng([seed, epoch, scene])``: a run does not depend on the loader's workers.

**Augmentation** (``augment = true``). As VGN: a rotation about the vertical axis by ``k · 90°`` (k uniform in
0..3) about the grid centre, applied at once to the grid and to every label: the grid is turned with
``numpy.rot90`` (lossless), a label at voxel coordinates ``c`` moves to ``m + R_z(k·90°)(c − m)`` with
``m = ((R − 1)/2, (R − 1)/2, ·)``, the centre of the voxel index range (VGN's convention: voxel ``i`` stands for
the coordinate ``i``), and its orientation becomes ``q_z(k·90°) ⊗ q`` (``R_grid_grasp ← R_z · R_grid_grasp``).
``z_shift = s > 0`` adds VGN's vertical translation, as a whole-grid shift by an integer ``dz`` uniform in
``[−s, s]`` voxels (zero filled; labels that leave the grid are dropped); off by default, since a single side
view of a table at a fixed height is what the detector sees.

**Loss**, averaged over the labelled voxels of the batch (VGN's per-grasp loss): at the voxel ``round(c)``,

    BCE(quality, label) + label · ( min_{t ∈ {q, q · R_x(π)}} (1 − |⟨q_pred, t⟩|) + 0.01 · (w_pred − w)² )

with ``q · R_x(π)`` the same grasp with its fingers swapped (this project's grasp frame: x approach), widths in
voxels. That is VGN's target (``rotation_target = "widest_run"``): ``q`` is the yaw in the middle of the widest
run of holding yaws. Where every yaw holds (a ball, the top of a can) that yaw is
an arbitrary world direction, and the k·90° augmentation then asks for four different answers to one picture.
``rotation_target = "any_holding"`` (data with every yaw's outcome, ``data.vgn_format``'s ``holds``) takes the
minimum over the whole holding set instead, ``min_{j : holds_j} ℓ(q_pred, q · R_x(j π / Y))`` (``ℓ`` the
two-form term above), so every yaw that held is a right answer. The held-out metrics then report
``rotation_hit``: the share of positives whose predicted rotation lies within 15° (geodesic) of a holding one.

Adam (lr 3e-4 as VGN), a batch of ``batch_size`` scenes; the network runs in the channels-last 3D
memory format (``VGNNet.use_channels_last``: 2.2× faster on the CPU).

**Run folder** ``out``: ``last.pt`` (``model.vgn_checkpoint`` format, with the optimiser and torch RNG states,
written atomically after every epoch), ``history.jsonl`` (one row per epoch: mean training loss and its
terms, held-out loss, accuracy, precision and recall of ``round(quality)`` against the labels at the
held-out scenes' labelled voxels, seconds; rewritten whole every epoch) and ``final.pt`` (weights only) at the
end. Calling ``train_vgn`` again resumes after the last completed epoch (raise ``epochs`` to train on); a
checkpoint of another dataset or of other settings (anything but ``epochs``, ``workers`` and the dataset
folder's path) is refused. The dataset is identified by the SHA-256 of the scenes the run uses
(``VGNManifest.prefix_sha256``: with ``max_scenes``, the first ``max_scenes``), so a run on a prefix resumes
after the dataset has grown.
``export_vgn`` writes the shipped weights and model card (``assets/weights/vgn.pt``, ``vgn.md``).

A config is a TOML file with one section ``[vgn]`` whose keys are the fields of ``VGNTrainConfig``.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.nn import functional as F
from torch.utils.data import DataLoader, Dataset

from kgn_bench.config import override_tables, parse_section, read_toml
from kgn_bench.data.format import DatasetError
from kgn_bench.data.vgn_format import SceneEntry, VGNManifest, read_manifest, read_scene
from kgn_bench.errors import KGNBenchError
from kgn_bench.io import atomic_write_text
from kgn_bench.lifecycle import loader_worker_init
from kgn_bench.model.checkpoint import CheckpointError, git_commit
from kgn_bench.model.vgn_checkpoint import (
    export_vgn_weights,
    load_vgn_checkpoint,
    save_vgn_checkpoint,
    vgn_payload,
)
from kgn_bench.model.vgn_network import VGNNet, VGNOutput
from kgn_bench.resources import weights_dir
from kgn_bench.shapes.library import test_set_leaks
from kgn_bench.training.train import machine_label

__all__ = [
    "HIT_ANGLE",
    "ROTATION_TARGETS",
    "VGNSceneDataset",
    "VGNTrainConfig",
    "VGNTrainConfigError",
    "collate_scenes",
    "export_vgn",
    "flip_x",
    "held_out_metrics",
    "holding_hits",
    "holding_rotation_loss",
    "load_vgn_train_config",
    "negatives_per_scene",
    "quat_multiply",
    "rotate_scene",
    "rotation_loss",
    "shift_scene",
    "split_scenes",
    "train_vgn",
    "turned",
    "vgn_loss",
]


ROTATION_TARGETS = ("widest_run", "any_holding")
"""The rotation targets a run can train on (``VGNTrainConfig.rotation_target``)."""
HIT_ANGLE = np.deg2rad(15.0)
"""A predicted rotation within this geodesic angle of a holding one counts as a hit (half the 30° yaw step)."""


class VGNTrainConfigError(KGNBenchError, ValueError):
    """A malformed VGN training config."""


@dataclass(frozen=True)
class VGNTrainConfig:
    """A VGN training run (module docstring). ``data``: the dataset folder. ``epochs`` (GIGA trains VGN for
    10), ``batch_size`` (scenes per step), ``lr`` (Adam), ``augment`` (the k·90° rotation), ``z_shift`` (voxels,
    0 = off), ``balance`` (drop negatives to as many as positives), ``seed`` (initial weights, split, every
    draw), ``held_out`` (fraction of the scenes kept out of training for the metrics), ``max_scenes`` (use only
    the first N scenes by id; 0 = all), ``workers`` (data-loading processes)."""

    data: str = ""
    out: str = ""
    """The run folder ``kgn-bench train`` writes to (``train_vgn`` takes its own)."""
    epochs: int = 10
    batch_size: int = 8
    lr: float = 3e-4
    augment: bool = True
    z_shift: int = 0
    balance: bool = True
    seed: int = 0
    held_out: float = 0.1
    max_scenes: int = 0
    workers: int = 0
    rotation_target: str = "widest_run"
    """``widest_run`` (VGN's: the stored yaw) or ``any_holding`` (any yaw that held; module docstring)."""

    def __post_init__(self) -> None:
        if not self.data:
            raise ValueError("data must name the dataset folder")
        if self.epochs < 1 or self.batch_size < 1 or not self.lr > 0:
            raise ValueError("epochs and batch_size must be ≥ 1 and lr > 0")
        if not 0.0 <= self.held_out < 1.0:
            raise ValueError(f"held_out must lie in [0, 1), got {self.held_out}")
        if self.z_shift < 0 or self.max_scenes < 0 or self.workers < 0:
            raise ValueError("z_shift, max_scenes and workers must be ≥ 0")
        if self.rotation_target not in ROTATION_TARGETS:
            raise ValueError(f"rotation_target must be one of {', '.join(ROTATION_TARGETS)}, "
                             f"got {self.rotation_target!r}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def load_vgn_train_config(path: Path, settings: list[tuple[str, str]] = ()) -> VGNTrainConfig:
    """Parse a VGN training TOML (one ``[vgn]`` section), with ``settings`` (``("vgn.epochs", "2")``) set over
    it; ``VGNTrainConfigError`` (one line) on any problem."""
    path = Path(path)
    raw = override_tables(read_toml(path, "VGN training config", VGNTrainConfigError), list(settings), str(path),
                          VGNTrainConfigError)
    unknown = sorted(set(raw) - {"vgn"})
    if unknown:
        raise VGNTrainConfigError(f"{path}: unknown section(s) {', '.join(unknown)} (known: vgn)")
    return parse_section(f"{path} [vgn]", VGNTrainConfig, raw.get("vgn", {}), VGNTrainConfigError)


# -- quaternions (w, x, y, z) -------------------------------------------------------------------------------


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` of (..., 4) quaternions (w, x, y, z): the rotation ``R(a) · R(b)``."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def flip_x(q: torch.Tensor) -> torch.Tensor:
    """``q ⊗ (0, 1, 0, 0)``: the grasp turned 180° about its own x (approach) axis, i.e. the same grasp with
    its fingers swapped; for ``q = (w, x, y, z)`` that is ``(−x, w, z, −y)``. (..., 4) tensors."""
    w, x, y, z = q.unbind(-1)
    return torch.stack([-x, w, z, -y], dim=-1)


def rotation_loss(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """(M,) ``min(1 − |⟨p, t⟩|, 1 − |⟨p, t · R_x(π)⟩|)`` for (M, 4) unit quaternions: 0 when ``p`` is the
    grasp ``t`` in either of its two forms (or their negatives), 1 at the farthest."""
    a = 1.0 - (pred * target).sum(-1).abs()
    b = 1.0 - (pred * flip_x(target)).sum(-1).abs()
    return torch.minimum(a, b)


def turned(target: torch.Tensor, turns: int) -> torch.Tensor:
    """(M, Y, 4): ``t · R_x(j π / Y)`` for ``j = 0..Y−1`` (``Y = turns``), each grasp ``t`` (M, 4) turned about its
    own approach axis by the yaw steps of its label (``data.vgn_format``'s ``holds``)."""
    half = torch.arange(turns, dtype=target.dtype, device=target.device) * (math.pi / (2 * turns))
    c, s_ = torch.cos(half)[None, :], torch.sin(half)[None, :]
    w, x, y, z = (v[:, None] for v in target.unbind(-1))
    return torch.stack([w * c - x * s_, x * c + w * s_, y * c + z * s_, z * c - y * s_], dim=-1)


def holding_rotation_loss(pred: torch.Tensor, target: torch.Tensor, holds: torch.Tensor) -> torch.Tensor:
    """(M,) ``min_{j : holds_j} rotation_loss(p, t · R_x(j π / Y))`` for predictions and stored rotations (M, 4)
    and ``holds`` (M, Y) bool: 0 when ``p`` is any grasp that held. Rows without a holding turn (negatives) get
    ``rotation_loss(p, t)``."""
    turns = turned(target, holds.shape[1])
    each = rotation_loss(pred[:, None, :].expand_as(turns), turns)
    best = torch.where(holds, each, torch.full_like(each, 2.0)).amin(dim=1)
    return torch.where(holds.any(dim=1), best, each[:, 0])


def holding_hits(pred: torch.Tensor, target: torch.Tensor, holds: torch.Tensor) -> torch.Tensor:
    """(M,) bool: whether each prediction lies within ``HIT_ANGLE`` (geodesic) of a rotation that held, for
    predictions and stored rotations (M, 4) and ``holds`` (M, Y). ``rotation_loss`` is ``1 − cos(θ/2)`` for a
    geodesic angle ``θ``, so the test is ``holding_rotation_loss ≤ 1 − cos(HIT_ANGLE / 2)``."""
    return holding_rotation_loss(pred, target, holds) <= 1.0 - math.cos(HIT_ANGLE / 2.0)


# -- augmentation ----------------------------------------------------------------------------------------------


def rotate_scene(tsdf: np.ndarray, voxels: np.ndarray, quats: np.ndarray, k: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scene turned by ``k · 90°`` about the vertical axis through the grid centre (module docstring):
    ``(rot90(tsdf, k, axes=(0, 1)), m + R_z(c − m), q_z ⊗ q)``. ``numpy.rot90`` over the axes (0, 1) moves the
    element ``[a, b]`` to ``[R − 1 − b, a]``, i.e. ``(x, y) → (−y, x)`` about ``m``: ``R_z(+90°)``."""
    k %= 4
    if k == 0:
        return tsdf, voxels, quats
    r = tsdf.shape[0]
    m = (r - 1) / 2.0
    angle = k * np.pi / 2.0
    c, s = round(np.cos(angle)), round(np.sin(angle))
    x, y = voxels[:, 0] - m, voxels[:, 1] - m
    out = np.stack([m + c * x - s * y, m + s * x + c * y, voxels[:, 2]], axis=1).astype(voxels.dtype)
    qz = np.array([np.cos(angle / 2.0), 0.0, 0.0, np.sin(angle / 2.0)])
    return (np.ascontiguousarray(np.rot90(tsdf, k, axes=(0, 1))), out,
            quat_multiply(qz, quats).astype(quats.dtype))


def shift_scene(tsdf: np.ndarray, voxels: np.ndarray, dz: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The grid moved ``dz`` voxels along k (zero filled) and the labels with it; returns the grid, the moved
    voxel coordinates and the mask of labels still inside the grid (rounded index in ``[0, R − 1]``)."""
    r = tsdf.shape[2]
    out = np.zeros_like(tsdf)
    if dz >= 0:
        out[:, :, dz:] = tsdf[:, :, : r - dz]
    else:
        out[:, :, :dz] = tsdf[:, :, -dz:]
    moved = voxels + np.array([0.0, 0.0, dz], dtype=voxels.dtype)
    kz = np.round(moved[:, 2])
    return out, moved, (kz >= 0) & (kz <= r - 1)


# -- data ----------------------------------------------------------------------------------------------------


def split_scenes(manifest: VGNManifest, held_out: float, seed: int, max_scenes: int = 0
                 ) -> tuple[list[SceneEntry], list[SceneEntry]]:
    """(train, held-out) scenes: the first ``max_scenes`` by id (0 = all), then ``round(held_out · n)``
    (at least 1 when ``held_out > 0`` and there are 2 scenes or more) drawn by ``default_rng(seed)``."""
    scenes = list(manifest.scenes[:max_scenes] if max_scenes else manifest.scenes)
    n = len(scenes)
    n_held = min(n - 1, max(1, round(held_out * n))) if held_out > 0 and n >= 2 else 0
    held = set(np.random.default_rng(seed).permutation(n)[:n_held].tolist())
    return ([s for i, s in enumerate(scenes) if i not in held], [s for i, s in enumerate(scenes) if i in held])


def negatives_per_scene(scenes: list[SceneEntry], rng: np.random.Generator) -> np.ndarray:
    """How many negatives each scene keeps so that the split holds as many negatives as positives: one
    multivariate hypergeometric draw of ``min(P, N)`` among all ``N`` negatives (int array, one per scene)."""
    negatives = np.array([s.negatives for s in scenes], dtype=np.int64)
    total = int(negatives.sum())
    keep = min(sum(s.positives for s in scenes), total)
    if keep == total:
        return negatives
    return rng.multivariate_hypergeometric(negatives, keep)


class VGNSceneDataset(Dataset):
    """The scenes of one split as training samples (module docstring: balance, augmentation). Item ``n`` is a
    dict: ``tsdf`` (1, R, R, R) float32, ``index`` (M, 3) long (rounded voxel, clipped into the grid),
    ``quat`` (M, 4), ``width`` (M,) voxels, ``label`` (M,) float32, and ``holds`` (M, Y) bool where the data
    stores every yaw's outcome. ``set_epoch`` redraws the balance."""

    def __init__(self, folder: Path, scenes: list[SceneEntry], seed: int, augment: bool = False, z_shift: int = 0,
                 balance: bool = True) -> None:
        self.folder, self.scenes, self.seed = Path(folder), list(scenes), seed
        self.augment, self.z_shift, self.balance = augment, z_shift, balance
        self.set_epoch(0)

    def set_epoch(self, epoch: int) -> None:
        """Draw the epoch's balance (how many negatives each scene keeps) and its augmentations."""
        self.epoch = epoch
        if self.balance:
            self.keep_negatives = negatives_per_scene(self.scenes, np.random.default_rng([self.seed, epoch]))
        else:
            self.keep_negatives = np.array([s.negatives for s in self.scenes], dtype=np.int64)

    def __len__(self) -> int:
        return len(self.scenes)

    def labels(self) -> tuple[int, int]:
        """(positives, negatives) this epoch."""
        return sum(s.positives for s in self.scenes), int(self.keep_negatives.sum())

    def __getitem__(self, n: int) -> dict[str, torch.Tensor]:
        scene = read_scene(self.folder, self.scenes[n])
        rng = np.random.default_rng([self.seed, self.epoch, n])
        labels = scene.labels.astype(bool)
        negatives = np.flatnonzero(~labels)
        chosen = rng.choice(negatives, size=int(self.keep_negatives[n]), replace=False)
        keep = np.sort(np.concatenate([np.flatnonzero(labels), chosen]).astype(np.int64))
        tsdf, voxels, quats = scene.tsdf, scene.voxels[keep], scene.quats[keep]
        widths, label = scene.widths[keep], scene.labels[keep]
        holds = None if scene.holds is None else scene.holds[keep]
        if self.augment:
            # turns are relative to the grasp's own frame: a turn of the scene leaves them as they are
            tsdf, voxels, quats = rotate_scene(tsdf, voxels, quats, int(rng.integers(4)))
            if self.z_shift:
                tsdf, voxels, inside = shift_scene(tsdf, voxels, int(rng.integers(-self.z_shift, self.z_shift + 1)))
                voxels, quats, widths, label = voxels[inside], quats[inside], widths[inside], label[inside]
                holds = None if holds is None else holds[inside]
        r = tsdf.shape[0]
        index = np.clip(np.round(voxels), 0, r - 1).astype(np.int64)
        item = {"tsdf": torch.from_numpy(np.ascontiguousarray(tsdf, dtype=np.float32))[None],
                "index": torch.from_numpy(index.reshape(-1, 3)),
                "quat": torch.from_numpy(np.asarray(quats, dtype=np.float32).reshape(-1, 4)),
                "width": torch.from_numpy(np.asarray(widths, dtype=np.float32)),
                "label": torch.from_numpy(np.asarray(label, dtype=np.float32))}
        if holds is not None:
            item["holds"] = torch.from_numpy(np.ascontiguousarray(holds, dtype=bool))
        return item


def collate_scenes(batch: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
    """A batch of scenes: ``tsdf`` (B, 1, R, R, R), ``index`` (M, 4) = (scene in batch, i, j, k) and the
    labels of all scenes concatenated (``quat`` (M, 4), ``width`` (M,), ``label`` (M,), and ``holds`` (M, Y)
    when every scene has them)."""
    index = torch.cat([F.pad(item["index"], (1, 0), value=b) for b, item in enumerate(batch)])
    keys = ("quat", "width", "label") + (("holds",) if all("holds" in item for item in batch) else ())
    return {"tsdf": torch.stack([item["tsdf"] for item in batch]), "index": index,
            **{key: torch.cat([item[key] for item in batch]) for key in keys}}


def vgn_loss(out: VGNOutput, batch: dict[str, torch.Tensor], rotation_target: str = "widest_run"
             ) -> tuple[torch.Tensor, dict[str, float]]:
    """The mean over the batch's labelled voxels of ``BCE + label · (rotation term + 0.01 · Δw²)`` (module
    docstring; the rotation term ``rotation_loss`` against the stored yaw, or ``holding_rotation_loss`` for
    ``rotation_target = "any_holding"``, which needs the batch's ``holds``) and its parts as floats: ``loss``,
    ``bce`` (mean over all labels), ``rotation`` and ``width`` (means over the positives; 0 without any),
    ``labels`` (how many)."""
    b, i, j, k = batch["index"].unbind(1)
    label = batch["label"]
    if len(label) == 0:
        zero = out.quality.sum() * 0.0
        return zero, {"loss": 0.0, "bce": 0.0, "rotation": 0.0, "width": 0.0, "labels": 0}
    quality = out.quality[b, 0, i, j, k].clamp(1e-7, 1 - 1e-7)
    bce = F.binary_cross_entropy(quality, label, reduction="none")
    pred = out.rotation[b, :, i, j, k]
    if rotation_target == "any_holding":
        rot = holding_rotation_loss(pred, batch["quat"], batch["holds"])
    else:
        rot = rotation_loss(pred, batch["quat"])
    width = 0.01 * (out.width[b, 0, i, j, k] - batch["width"]) ** 2
    loss = (bce + label * (rot + width)).mean()
    with torch.no_grad():
        positives = float(label.sum())
        parts = {"loss": float(loss.detach()), "bce": float(bce.mean()),
                 "rotation": float((label * rot).sum()) / positives if positives else 0.0,
                 "width": float((label * width).sum()) / positives if positives else 0.0, "labels": len(label)}
    return loss, parts


def _to(batch: dict[str, torch.Tensor], device: torch.device) -> dict[str, torch.Tensor]:
    return {k: v.to(device, non_blocking=device.type == "cuda") for k, v in batch.items()}


def held_out_metrics(net: VGNNet, loader: DataLoader, device: torch.device, rotation_target: str = "widest_run"
                     ) -> dict[str, float | None]:
    """``held_out_loss`` (mean over labels, the run's ``rotation_target``), ``accuracy``, ``precision`` and
    ``recall`` of ``round(quality)`` at the labelled voxels of every scene the loader yields, and, where the data
    stores every yaw's outcome, ``rotation_hit``: the share of positives whose predicted rotation lies within
    ``HIT_ANGLE`` of a holding one (None where undefined, e.g. no predicted positive). The network is in eval
    mode during the call and back in its previous mode after."""
    was_training = net.training
    net.eval()
    tp = fp = tn = fn = 0
    loss_sum, count = 0.0, 0
    hits, positives, with_holds = 0, 0, True
    with torch.inference_mode():
        for batch in loader:
            batch = _to(batch, device)
            out = net(batch["tsdf"])
            loss, parts = vgn_loss(out, batch, rotation_target)
            if "holds" in batch:
                b, i, j, k = batch["index"].unbind(1)
                pos = batch["label"] > 0.5
                hits += int(holding_hits(out.rotation[b, :, i, j, k][pos], batch["quat"][pos],
                                         batch["holds"][pos]).sum())
                positives += int(pos.sum())
            else:
                with_holds = False
            loss_sum += float(loss) * parts["labels"]
            count += parts["labels"]
            b, i, j, k = batch["index"].unbind(1)
            pred = out.quality[b, 0, i, j, k] >= 0.5
            truth = batch["label"] > 0.5
            tp += int((pred & truth).sum())
            fp += int((pred & ~truth).sum())
            tn += int((~pred & ~truth).sum())
            fn += int((~pred & truth).sum())
    net.train(was_training)
    metrics: dict[str, float | None] = {"held_out_loss": loss_sum / count if count else None,
                                        "accuracy": (tp + tn) / count if count else None,
                                        "precision": tp / (tp + fp) if tp + fp else None,
                                        "recall": tp / (tp + fn) if tp + fn else None}
    if with_holds and count:
        metrics["rotation_hit"] = hits / positives if positives else None
    return metrics


# -- the run --------------------------------------------------------------------------------------------------


def _loader(dataset: VGNSceneDataset, cfg: VGNTrainConfig, device: torch.device, shuffle_seed: int | None
            ) -> DataLoader:
    generator = torch.Generator().manual_seed(shuffle_seed) if shuffle_seed is not None else None
    return DataLoader(dataset, batch_size=cfg.batch_size, shuffle=shuffle_seed is not None, drop_last=False,
                      num_workers=cfg.workers, collate_fn=collate_scenes, pin_memory=device.type == "cuda",
                      generator=generator, worker_init_fn=loader_worker_init)


def _comparable(config: dict[str, Any]) -> dict[str, Any]:
    """The settings a resumed run must share with its checkpoint: all but ``epochs``, ``workers`` and ``data``
    (the dataset is compared by its SHA-256, so a moved dataset folder resumes)."""
    return {k: v for k, v in config.items() if k not in ("epochs", "workers", "data", "out")}


def train_vgn(config: VGNTrainConfig, out: Path, threads: int | None = 1, device: str | None = None,
              progress: bool = False) -> Path:
    """Train (or resume) a VGN run in the folder ``out`` (module docstring); returns the path of ``final.pt``.

    ``threads``: torch's intra-op CPU threads (None: leave them). ``device``: ``cpu``, ``cuda``, ``cuda:1``...;
    None picks CUDA when available. ``DatasetError`` for an unusable dataset, ``CheckpointError`` for a
    ``last.pt`` of another dataset or other settings."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    dev = torch.device(device or ("cuda" if torch.cuda.is_available() else "cpu"))
    if threads:
        torch.set_num_threads(threads)
    torch.manual_seed(config.seed)
    manifest = read_manifest(Path(config.data))
    leaks = test_set_leaks(manifest.settings.get("objects", []))
    if leaks:
        raise DatasetError(f"{config.data}: its scenes hold real test objects ({', '.join(leaks[:5])}); never "
                           "train on them")
    train_scenes, held_scenes = split_scenes(manifest, config.held_out, config.seed, config.max_scenes)
    if not train_scenes:
        raise DatasetError(f"{config.data}: no training scene")
    if config.rotation_target == "any_holding" and read_scene(manifest.folder, train_scenes[0]).holds is None:
        raise DatasetError(f"{config.data}: rotation_target = 'any_holding' needs every yaw's outcome, which this "
                           "dataset does not store (label rule v4 on: regenerate it with `kgn-bench data vgn`)")
    train_set = VGNSceneDataset(manifest.folder, train_scenes, config.seed, config.augment, config.z_shift,
                                config.balance)
    held_set = VGNSceneDataset(manifest.folder, held_scenes, config.seed + 1, balance=config.balance)
    used = train_scenes + held_scenes
    identity = {"path": str(config.data), "sha256": manifest.prefix_sha256(config.max_scenes),
                "scenes": len(used),
                "train_scenes": len(train_scenes), "held_out_scenes": len(held_scenes),
                "grasps": sum(s.grasps for s in used), "positives": sum(s.positives for s in used),
                "generation_seconds": manifest.generation_seconds,
                "objects": len(manifest.settings.get("objects") or []), "labels": manifest.settings.get("labels")}
    net = VGNNet().to(dev).use_channels_last()
    optim = torch.optim.Adam(net.parameters(), lr=config.lr)
    commit, start, history = git_commit(), 0, []

    last = out / "last.pt"
    if last.exists():
        ckpt = load_vgn_checkpoint(last)
        if ckpt.get("dataset", {}).get("sha256") != identity["sha256"]:
            raise CheckpointError(f"{last} was trained on another dataset than {config.data} "
                                  "(use another run folder or delete it)")
        if _comparable(ckpt.get("train", {})) != _comparable(config.to_dict()):
            raise CheckpointError(f"{last} was written with other settings (only epochs, workers and the dataset's "
                                  "folder may change on resume)")
        net.load_state_dict(ckpt["model"])
        optim.load_state_dict(ckpt["optimizer"])
        start, history = int(ckpt["epoch"]), list(ckpt.get("history", []))
        commit = ckpt.get("git_commit", commit)
        torch.set_rng_state(ckpt["torch_rng"])

    def payload(epoch: int, with_optimizer: bool) -> dict[str, Any]:
        p = {**vgn_payload(net, manifest.grid), "train": config.to_dict(), "dataset": identity,
             "git_commit": commit, "machine": machine_label(dev), "epoch": epoch, "history": history}
        if with_optimizer:
            p["optimizer"] = optim.state_dict()
            p["torch_rng"] = torch.get_rng_state()
        return p

    held_loader = _loader(held_set, config, dev, None)
    net.train()
    for epoch in range(start, config.epochs):
        t0 = time.perf_counter()
        train_set.set_epoch(epoch)
        sums: dict[str, float] = {}
        labels = 0
        for batch in _loader(train_set, config, dev, config.seed * 1000 + epoch):
            batch = _to(batch, dev)
            loss, parts = vgn_loss(net(batch["tsdf"]), batch, config.rotation_target)
            if not math.isfinite(parts["loss"]):
                raise FloatingPointError(f"VGN loss became {parts['loss']} in epoch {epoch + 1}; lower lr")
            optim.zero_grad(set_to_none=True)
            loss.backward()
            optim.step()
            n = parts["labels"]
            labels += n
            for key in ("loss", "bce", "rotation", "width"):
                sums[key] = sums.get(key, 0.0) + parts[key] * n
        row: dict[str, Any] = {"epoch": epoch + 1, **{k: round(v / max(labels, 1), 6) for k, v in sums.items()},
                               "labels": labels}
        row.update(held_out_metrics(net, held_loader, dev, config.rotation_target) if len(held_set) else {})
        row["seconds"] = round(time.perf_counter() - t0, 2)
        history.append(row)
        atomic_write_text(out / "history.jsonl", "".join(json.dumps(h) + "\n" for h in history))
        save_vgn_checkpoint(last, payload(epoch + 1, with_optimizer=True))
        if progress:
            print(f"vgn epoch {epoch + 1}/{config.epochs}: " + " ".join(
                f"{k} {v:.4f}" for k, v in row.items() if isinstance(v, float)), flush=True)
    final = out / "final.pt"
    save_vgn_checkpoint(final, payload(len(history), with_optimizer=False))
    return final


def export_vgn(run: Path, name: str = "vgn", out_dir: Path | None = None) -> tuple[Path, Path]:
    """Write a run's weights (``final.pt``, else ``last.pt``) as ``<out_dir>/<name>.pt`` (float32, no optimiser,
    ~1.3 MB) and its model card ``<name>.md`` (data, grasps, epochs, wall time, machine, held-out metrics,
    the file's SHA-256); ``out_dir`` defaults to the shipped ``assets/weights``. Returns both paths."""
    run = Path(run)
    src = run / "final.pt" if (run / "final.pt").is_file() else run / "last.pt"
    if not src.is_file():
        raise CheckpointError(f"{run}: no final.pt or last.pt to export")
    return export_vgn_weights(src, name, weights_dir() if out_dir is None else Path(out_dir))
