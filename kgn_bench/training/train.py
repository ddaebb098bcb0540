"""Training KGN / KGNv2 from a TOML config: Adam with a step schedule, augmentation, checkpoints, resume.

A training config (``tasks/train_<variant>_<data>.toml``) has the sections

* ``[train]``: ``variant``, ``data`` (dataset folder), ``out`` (run folder), ``epochs``, ``batch_size``,
  ``lr``, ``lr_steps`` (epochs after which the rate is multiplied by ``lr_gamma``), ``seed``, ``workers``
  (data-loading processes), ``limit`` (use only the first N training views; 0 = all), ``eval_every``
  (epochs between held-out evaluations; 0 = only at the end), ``eval_views`` (test views evaluated),
  ``scale_anchor`` (``none`` or ``depth``: how the scale head is parameterised, ``model.depth_anchor``) and
  ``assignment`` (``first`` or ``frontal``: which grasp a shared (cell, bin) target takes,
  ``model.targets``);
* ``[network]`` (``NetworkConfig``), ``[input]`` (``InputConfig``), ``[augment]`` (``AugmentConfig``),
  ``[loss]`` (``LossWeights``); omitted keys take the defaults.

The run folder holds ``last.pt`` (written atomically after every epoch, with the optimizer and scheduler
states, the full config, the dataset identity and the git commit), ``history.jsonl`` (one line per
epoch: mean losses, learning rate, seconds and, when evaluated, GSR/GCR/OSR) and, at the end,
``final.pt`` (weights without optimizer state). Running the same command again resumes after the last
completed epoch; a config that differs from the checkpoint's is refused.
"""

from __future__ import annotations

import json
import math
import platform
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch
from torch.utils.data import DataLoader

from kgn_bench.config import parse_section, read_toml, resolve_task
from kgn_bench.data.format import DatasetError
from kgn_bench.data.training import AugmentConfig, GraspViewDataset
from kgn_bench.environment import cpu_model
from kgn_bench.errors import KGNBenchError
from kgn_bench.model.checkpoint import (
    CheckpointError,
    LoadedModel,
    dataset_identity,
    git_commit,
    load_checkpoint,
    model_payload,
    save_checkpoint,
)
from kgn_bench.model.losses import LossWeights, kgn_loss
from kgn_bench.model.network import NetworkConfig, build_network, count_parameters
from kgn_bench.model.preprocess import InputConfig
from kgn_bench.model.targets import ASSIGNMENTS
from kgn_bench.model.variants import get_variant
from kgn_bench.progress import Progress
from kgn_bench.threads import available_cores

__all__ = ["TrainConfig", "TrainConfigError", "load_train_config", "machine_label", "train"]


class TrainConfigError(KGNBenchError, ValueError):
    """A malformed training config."""


@dataclass(frozen=True)
class TrainSettings:
    variant: str = "kgnv2"
    data: str = "data/ps_multi"
    out: str = "runs/train_kgnv2_multi"
    epochs: int = 30
    batch_size: int = 16
    lr: float = 1e-3
    lr_steps: tuple[int, ...] = (22, 27)
    lr_gamma: float = 0.1
    seed: int = 317
    workers: int = 2
    limit: int = 0
    eval_every: int = 5
    eval_views: int = 100
    scale_anchor: str = "none"
    """``none``: the scale head regresses ‖t_cam‖ (the paper); ``depth``: its residual to the observed depth
    along the grasp centre's ray (``kgn_bench.model.depth_anchor``)."""
    assignment: str = "first"
    """Which grasp a (cell, bin) target takes: ``first`` (the reference) or ``frontal`` (``model.targets``)."""


@dataclass(frozen=True)
class TrainConfig:
    """Everything that defines a training run (see the module docstring)."""

    name: str
    train: TrainSettings = field(default_factory=TrainSettings)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    input: InputConfig = field(default_factory=InputConfig)
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    loss: LossWeights = field(default_factory=LossWeights)

    def to_dict(self) -> dict[str, Any]:
        return json.loads(json.dumps(asdict(self)))


def load_train_config(path: Path) -> TrainConfig:
    """Parse and validate a training TOML file; ``TrainConfigError`` (one line) on any problem."""
    path = resolve_task(path)
    raw = read_toml(path, "training config", TrainConfigError)
    sections = {"train": TrainSettings, "network": NetworkConfig, "input": InputConfig, "augment": AugmentConfig,
                "loss": LossWeights}
    unknown = sorted(set(raw) - set(sections))
    if unknown:
        raise TrainConfigError(f"{path}: unknown section(s) {', '.join(unknown)}")
    parts = {k: parse_section(f"{path} [{k}]", cls, raw.get(k, {}), TrainConfigError) for k, cls in sections.items()}
    cfg = TrainConfig(name=path.stem, **parts)
    t = cfg.train
    try:
        get_variant(t.variant).with_scale_anchor(t.scale_anchor)
    except ValueError as e:
        raise TrainConfigError(f"{path}: {e}") from None
    if t.assignment not in ASSIGNMENTS:
        raise TrainConfigError(f"{path}: unknown [train] assignment {t.assignment!r} (known: {', '.join(ASSIGNMENTS)})")
    if t.scale_anchor != "none" and not get_variant(t.variant).scale_branch:
        raise TrainConfigError(f"{path}: variant {t.variant!r} has no scale head to anchor (scale_anchor)")
    if get_variant(t.variant).weights_variant != t.variant:
        source = get_variant(t.variant).weights_variant
        raise TrainConfigError(f"{path}: variant {t.variant!r} is decoded from {source!r} weights; train that one")
    if t.epochs < 1 or t.batch_size < 1 or not t.lr > 0 or t.workers < 0 or t.limit < 0 or t.eval_every < 0:
        raise TrainConfigError(f"{path}: epochs and batch_size must be ≥ 1, lr > 0, workers/limit/eval_every ≥ 0")
    return cfg


def machine_label(device: torch.device) -> str:
    """Where a run trains, for its model card: architecture, CPU model, torch's CPU threads and the device,
    with the GPU's name on CUDA, e.g. ``x86_64, AMD EPYC, 2 threads, cpu``."""
    parts = [platform.machine(), cpu_model() or "unknown CPU", f"{torch.get_num_threads()} threads"]
    if device.type == "cuda":
        parts.append(torch.cuda.get_device_name(device))
    return ", ".join([*parts, device.type])


def _collate(batch):
    xs, targets = zip(*batch)
    return torch.stack(xs), {k: torch.stack([t[k] for t in targets]) for k in targets[0]}


def _lr_at(cfg: TrainSettings, epoch: int) -> float:
    return cfg.lr * cfg.lr_gamma ** sum(epoch >= s for s in cfg.lr_steps)


def _evaluate(net, cfg: TrainConfig, data: Path, views: int) -> dict[str, Any]:
    """GSR/GCR/OSR of the current weights on the first ``views`` test views."""
    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.vision import evaluate_dataset

    net.eval()
    variant = get_variant(cfg.train.variant).with_scale_anchor(cfg.train.scale_anchor)
    model = LoadedModel(net, variant, cfg.network, cfg.input, {})
    detector = KGNDetector(variant.name, model=model)
    metrics = evaluate_dataset(detector, data, split="test", views=views, progress=False)
    net.train()
    return metrics.summarise()


def train(cfg: TrainConfig, progress: bool = True, device: str | None = None, threads: int | None = None) -> Path:
    """Train (or resume) the run ``cfg.train.out``; returns the path of ``final.pt``.

    On the CPU, ``threads`` (default: torch's) sets the intra-op threads. On CUDA the same config trains
    with bfloat16 autocast (mixed precision; the weights and the optimiser stay float32) and at least
    ``min(8, cores − 1)`` data-loading processes; neither changes what a sample is, since augmentation is
    seeded per (seed, epoch, item).
    """
    t_cfg = cfg.train
    out = Path(t_cfg.out)
    out.mkdir(parents=True, exist_ok=True)
    data = Path(t_cfg.data)
    variant = get_variant(t_cfg.variant).with_scale_anchor(t_cfg.scale_anchor)
    dev = torch.device(device or ("cuda" if torch.cuda.is_available() else "cpu"))
    if threads:
        torch.set_num_threads(threads)
    cuda = dev.type == "cuda"
    loader_workers = max(t_cfg.workers, min(8, available_cores() - 1)) if cuda else t_cfg.workers
    torch.manual_seed(t_cfg.seed)

    dataset = GraspViewDataset(data, "train", variant, cfg.input, cfg.augment, seed=t_cfg.seed,
                               limit=t_cfg.limit or None, assignment=t_cfg.assignment)
    if len(dataset) < t_cfg.batch_size:
        raise DatasetError(f"{data}: {len(dataset)} training views, fewer than one batch of {t_cfg.batch_size}")
    identity = dataset_identity(data)
    net = build_network(variant, cfg.network).to(dev)
    optim = torch.optim.Adam(net.parameters(), lr=t_cfg.lr)
    start, history = 0, []
    commit = git_commit()  # the code that starts the run (kept across resumes)

    last = out / "last.pt"
    if last.exists():
        ckpt = load_checkpoint(last)
        if ckpt.get("train") != cfg.to_dict():
            raise CheckpointError(f"{last} was written by a different config; use another [train] out or delete it")
        if ckpt.get("dataset", {}).get("sha256") != identity["sha256"]:
            raise CheckpointError(f"{last} was trained on another dataset than {data}")
        net.load_state_dict(ckpt["model"])
        optim.load_state_dict(ckpt["optimizer"])
        start, history = int(ckpt["epoch"]), list(ckpt.get("history", []))
        commit = ckpt.get("git_commit", commit)
        torch.set_rng_state(ckpt["torch_rng"])

    def payload(epoch: int, with_optimizer: bool) -> dict[str, Any]:
        p = {
            **model_payload(net, variant.name, cfg.network, cfg.input, variant.scale_anchor),
            "train": cfg.to_dict(),
            "dataset": identity,
            "git_commit": commit,
            "epoch": epoch,
            "history": history,
            "parameters": count_parameters(net),
            "machine": machine_label(dev),
        }
        if with_optimizer:
            p["optimizer"] = optim.state_dict()
            p["torch_rng"] = torch.get_rng_state()
        return p

    net.train()
    for epoch in range(start, t_cfg.epochs):
        dataset.set_epoch(epoch)
        for group in optim.param_groups:
            group["lr"] = _lr_at(t_cfg, epoch)
        loader = DataLoader(dataset, batch_size=t_cfg.batch_size, shuffle=True, drop_last=True,
                            num_workers=loader_workers, collate_fn=_collate, persistent_workers=False,
                            pin_memory=cuda, generator=torch.Generator().manual_seed(t_cfg.seed * 1000 + epoch))
        bar = Progress(len(loader), f"epoch {epoch + 1}/{t_cfg.epochs}", unit="batch", enabled=progress)
        sums: dict[str, float] = {}
        t0 = time.perf_counter()
        for x, targets in loader:
            x = x.to(dev, non_blocking=cuda)
            targets = {k: v.to(dev, non_blocking=cuda) for k, v in targets.items()}
            with torch.autocast("cuda", dtype=torch.bfloat16, enabled=cuda):
                outputs = net(x)
            loss, parts = kgn_loss({k: v.float() for k, v in outputs.items()}, targets, variant, cfg.loss)
            if not math.isfinite(parts["total"]):
                raise FloatingPointError(f"loss became {parts['total']} in epoch {epoch + 1}; lower [train] lr")
            optim.zero_grad(set_to_none=True)
            loss.backward()
            optim.step()
            for k, v in parts.items():
                sums[k] = sums.get(k, 0.0) + v
            bar.update(1, " ".join(f"{k} {v:.3f}" for k, v in parts.items()))
        row: dict[str, Any] = {"epoch": epoch + 1, "lr": _lr_at(t_cfg, epoch),
                               "seconds": round(time.perf_counter() - t0, 1)}
        row.update({k: round(v / max(len(loader), 1), 5) for k, v in sums.items()})
        done = epoch + 1
        if (t_cfg.eval_every and done % t_cfg.eval_every == 0) or done == t_cfg.epochs:
            summary = _evaluate(net, cfg, data, t_cfg.eval_views)
            row["eval"] = {t["label"]: {k: t[k] for k in ("gsr", "gcr", "osr")} for t in summary["thresholds"]}
            row["eval_views"] = summary["images"]
        history.append(row)
        with (out / "history.jsonl").open("a") as f:
            f.write(json.dumps(row) + "\n")
        save_checkpoint(last, payload(done, with_optimizer=True))
        if progress:
            print(f"epoch {done}: " + " ".join(f"{k} {row[k]}" for k in ("total", "hm", "kpts", "width", "scale")
                                               if k in row), flush=True)
    final = out / "final.pt"
    save_checkpoint(final, payload(t_cfg.epochs, with_optimizer=False))
    return final
