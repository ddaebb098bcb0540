"""VGN weights on disk: one ``.pt`` file that rebuilds ``VGNNet``, and its Markdown model card.

A VGN checkpoint is a ``torch.save`` dict:

``format`` ("kgn-bench-vgn"), ``version``, ``model`` (``VGNNet`` state dict, float32 on the CPU),
``grid`` (the ``VoxelGrid`` the network was trained on: ``size`` m, ``resolution``, ``truncation_voxels``),
``parameters``, and what the training run adds: ``train`` (its ``VGNTrainConfig`` as a dict), ``dataset``
(the dataset folder, its manifest counts and SHA-256), ``git_commit``, ``machine``, ``epoch`` (completed
epochs), ``history`` (one row per epoch: losses, held-out accuracy / precision / recall, seconds) and, in
training checkpoints only, ``optimizer`` and ``torch_rng`` (stripped from shipped weights).

Files are written atomically (``io.atomic_write``). A shipped file is checked against the SHA-256 of its
model card (``<name>.md`` beside it, as for the KGN weights: ``checkpoint.verify_weights``). A missing,
damaged or foreign file is one ``CheckpointError`` line naming it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from kgn_bench.io import atomic_write, atomic_write_text
from kgn_bench.model.checkpoint import CheckpointError, file_sha256, read_checkpoint
from kgn_bench.model.vgn_network import VGNNet
from kgn_bench.tsdf import VoxelGrid

__all__ = [
    "VGN_FORMAT",
    "VGN_VERSION",
    "LoadedVGN",
    "export_vgn_weights",
    "load_vgn_checkpoint",
    "load_vgn_model",
    "save_vgn_checkpoint",
    "vgn_model_card",
    "vgn_payload",
]

VGN_FORMAT = "kgn-bench-vgn"
VGN_VERSION = 1


def vgn_payload(net: VGNNet, grid: VoxelGrid) -> dict[str, Any]:
    """The entries that rebuild a network: ``model`` (state dict on the CPU), ``grid`` and ``parameters``."""
    return {
        "model": {k: v.detach().cpu().contiguous() for k, v in net.state_dict().items()},
        "grid": {"size": grid.size, "resolution": grid.resolution, "truncation_voxels": grid.truncation_voxels},
        "parameters": sum(p.numel() for p in net.parameters()),
    }


def save_vgn_checkpoint(path: Path, payload: dict[str, Any]) -> None:
    """Atomically write ``payload`` (completed with ``format`` and ``version``) to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {"format": VGN_FORMAT, "version": VGN_VERSION, **payload}
    atomic_write(path, lambda f: torch.save(data, f))


def load_vgn_checkpoint(path: Path) -> dict[str, Any]:
    """The checkpoint dict at ``path``; ``CheckpointError`` (one line naming the file) if it is missing,
    differs from its model card's SHA-256, is unreadable, of another format or version, or lacks an entry."""
    return read_checkpoint(path, VGN_FORMAT, VGN_VERSION, ("model", "grid"), what="VGN checkpoint",
                           missing=f"no VGN weights at {path} (train them: kgn_bench.training.vgn_train)")


@dataclass
class LoadedVGN:
    """A ``VGNNet`` in eval mode, the ``VoxelGrid`` it expects and the checkpoint's other entries."""

    net: VGNNet
    grid: VoxelGrid
    meta: dict[str, Any] = field(default_factory=dict)


def load_vgn_model(path: Path) -> LoadedVGN:
    """Build ``VGNNet`` from the checkpoint at ``path`` (on the CPU, eval mode, channels-last 3D);
    ``CheckpointError`` if the file is refused (``load_vgn_checkpoint``) or its weights or grid do not fit."""
    data = load_vgn_checkpoint(path)
    try:
        g = data["grid"]
        grid = VoxelGrid(float(g["size"]), int(g["resolution"]), float(g["truncation_voxels"]))
    except (TypeError, KeyError, ValueError) as e:
        raise CheckpointError(f"{path}: bad voxel grid in the checkpoint ({type(e).__name__})") from None
    if grid.resolution % 8:
        raise CheckpointError(f"{path}: a {grid.resolution}³ grid; VGN needs a resolution divisible by 8")
    net = VGNNet()
    try:
        net.load_state_dict(data["model"])
    except (RuntimeError, KeyError, TypeError, AttributeError) as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise CheckpointError(f"{path}: weights do not fit VGN ({first})") from None
    net.eval().use_channels_last()
    meta = {k: v for k, v in data.items() if k not in ("model", "optimizer", "torch_rng")}
    return LoadedVGN(net, grid, meta)


def vgn_model_card(data: dict[str, Any], name: str, size_bytes: int, sha256: str | None = None) -> str:
    """A Markdown model card from a VGN checkpoint dict: the weights file's SHA-256 (checked on every load),
    data, schedule, wall time, machine, commit and the last epoch's held-out metrics."""
    train = data.get("train", {})
    history = data.get("history", [])
    last = history[-1] if history else {}
    ds = data.get("dataset", {})
    grid = data.get("grid", {})
    seconds = sum(h.get("seconds", 0.0) for h in history)
    lines = [
        f"# {name}",
        "",
        "VGN (Breyer et al., CoRL 2020) as GIGA re-trained it for one noisy side view: the `vgn` detector.",
        "",
        "| field | value |",
        "| --- | --- |",
        "| network | `VGNNet` (kgn_bench.model.vgn_network) |",
        *([f"| sha256 | `{sha256}` |"] if sha256 else []),
        f"| parameters | {data.get('parameters', 'n/a')} |",
        f"| file size | {size_bytes / 1e6:.1f} MB |",
        f"| grid | {grid.get('resolution', '?')}³ voxels over {grid.get('size', '?')} m, truncation "
        f"{grid.get('truncation_voxels', '?')} voxels |",
        f"| data | `{ds.get('path', '?')}`: {ds.get('scenes', '?')} scenes ({ds.get('train_scenes', '?')} train, "
        f"{ds.get('held_out_scenes', '?')} held out), {ds.get('grasps', '?')} labelled grasps, "
        f"{ds.get('positives', '?')} positive (sha256 {str(ds.get('sha256', ''))[:12]}) |",
        *([f"| data generation | {ds['generation_seconds'] / 3600:.1f} core-hours (every scene of the folder: "
            f"arranging, viewing, labelling in physics), {ds.get('objects', '?')} object types, label rule "
            f"`{ds.get('labels', '?')}` |"] if ds.get("generation_seconds") else []),
        f"| epochs | {data.get('epoch', '?')} (batch {train.get('batch_size', '?')} scenes, Adam lr "
        f"{train.get('lr', '?')}, augment {train.get('augment', '?')}, seed {train.get('seed', '?')}) |",
        f"| wall time | {seconds / 60:.0f} min |",
        f"| machine | {data.get('machine', '?')} |",
        f"| git commit | `{data.get('git_commit', '?')}` |",
    ]
    if last:
        lines.append(f"| final loss (epoch {last.get('epoch')}) | train {_num(last.get('loss'))}, "
                     f"held-out {_num(last.get('held_out_loss'))} |")
        hit = (f", rotation within 15° of a holding one {_pct(last['rotation_hit'])}"
               if last.get("rotation_hit") is not None else "")
        lines.append(f"| held-out (epoch {last.get('epoch')}) | accuracy {_pct(last.get('accuracy'))}, precision "
                     f"{_pct(last.get('precision'))}, recall {_pct(last.get('recall'))}{hit} |")
    if history:
        lines += ["", "Training curve (epoch: train loss / held-out accuracy): "
                  + ", ".join(f"{h.get('epoch')}: {_num(h.get('loss'), 3)} / {_pct(h.get('accuracy'))}"
                              for h in history),
                  "", f"![training curves]({name}_training.png)"]
    return "\n".join(lines) + "\n"


def _pct(x: float | None) -> str:
    return "n/a" if x is None else f"{100 * x:.1f} %"


def _num(x: float | None, digits: int = 4) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"


def export_vgn_weights(src: Path, name: str, out_dir: Path) -> tuple[Path, Path]:
    """Copy a VGN checkpoint's weights (no optimiser state) to ``out_dir/<name>.pt`` and write its model card
    ``out_dir/<name>.md`` (with the new file's SHA-256); returns both paths."""
    data = load_vgn_checkpoint(src)
    slim = {k: v for k, v in data.items() if k not in ("optimizer", "torch_rng", "format", "version")}
    slim["model"] = {k: v.to(torch.float32) if v.is_floating_point() else v for k, v in slim["model"].items()}
    out_dir = Path(out_dir)
    weights = out_dir / f"{name}.pt"
    card = out_dir / f"{name}.md"
    card.unlink(missing_ok=True)  # an old card's SHA-256 would refuse the new file until the new card is written
    save_vgn_checkpoint(weights, slim)
    atomic_write_text(card, vgn_model_card(slim, name, weights.stat().st_size, file_sha256(weights)))
    return weights, card
