"""Training KGN / KGNv2 from a TOML config: Adam with a step schedule, augmentation, checkpoints, resume.

A training config (``tasks/train_<variant>_<data>.toml``) has the sections

* ``[train]``: ``variant``, ``data`` (dataset folder), ``out`` (run folder), ``epochs``, ``batch_size``,
  ``lr``, ``lr_steps`` (epochs after which the rate is multiplied by ``lr_gamma``), ``seed``, ``workers``
  (data-loading processes), ``limit`` (use only the first N training views; 0 = all), ``eval_every``
  (epochs between held-out evaluations; 0 = only at the end), ``eval_views`` (test views evaluated),
  ``scale_anchor`` (``none`` or ``depth``: how the scale head is parameterised, ``model.depth_anchor``) and
  ``assignment`` (``first`` or ``frontal``: which grasp a shared (cell, bin) target takes,
  ``model.targets``), ``precision`` (``auto``, ``float32`` or ``bfloat16``: see ``autocast_dtype``),
  ``extra_data`` (further dataset folders whose training splits join ``data``'s; the held-out evaluation
  stays on ``data``'s test split) and ``init`` (a checkpoint to start from instead of the seed's random
  weights: fine-tuning; same variant, scale anchor and network);
* ``[network]`` (``NetworkConfig``), ``[input]`` (``InputConfig``), ``[augment]`` (``AugmentConfig``),
  ``[loss]`` (``LossWeights``); omitted keys take the defaults.

The run folder holds ``last.pt`` (written atomically after every epoch, with the optimizer and scheduler
states, the full config, the dataset identity and the git commit), ``history.jsonl`` (one line per
epoch: mean losses, learning rate, seconds and, when evaluated, GSR/GCR/OSR) and, at the end,
``final.pt`` (weights without optimizer state). Running the same command again resumes after the last
completed epoch; a config that differs from the checkpoint's is refused.

The held-out evaluation is passed in (``train(..., evaluate=...)``, a ``HeldOutEvaluator``): this module
imports neither the detectors nor the evaluation code. ``kgn-bench train`` passes
``eval.vision.held_out_evaluator``; without an evaluator no epoch is evaluated.
"""

from __future__ import annotations

import hashlib
import json
import math
import platform
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch
from torch.utils.data import ConcatDataset, DataLoader

from kgn_bench.config import override_tables, parse_section, read_toml, resolve_task
from kgn_bench.data.format import DatasetError
from kgn_bench.environment import cpu_model
from kgn_bench.errors import KGNBenchError, warn
from kgn_bench.kernels import cpu_flags
from kgn_bench.kernels import mode as kernels_mode
from kgn_bench.lifecycle import loader_worker_init
from kgn_bench.model.checkpoint import (
    CheckpointError,
    LoadedModel,
    dataset_identity,
    file_sha256,
    git_commit,
    load_checkpoint,
    model_payload,
    save_checkpoint,
)
from kgn_bench.model.losses import LossWeights, kgn_loss
from kgn_bench.model.network import KGNNet, NetworkConfig, build_network, count_parameters
from kgn_bench.model.preprocess import InputConfig
from kgn_bench.model.targets import ASSIGNMENTS
from kgn_bench.model.variants import Variant, get_variant
from kgn_bench.progress import Progress
from kgn_bench.shapes.library import test_set_leaks
from kgn_bench.threads import available_cores
from kgn_bench.training.dataset import AugmentConfig, GraspViewDataset

__all__ = ["PRECISIONS", "HeldOutEvaluator", "TrainConfig", "TrainConfigError", "autocast_dtype", "bfloat16_emulated",
           "load_train_config",
           "machine_label", "train", "train_step"]

PRECISIONS = ("auto", "float32", "bfloat16")
"""The values of ``[train] precision``."""
BF16_FLAGS = frozenset({"avx512_bf16", "amx_bf16"})
"""CPU flags of native bfloat16 arithmetic: without them oneDNN emulates it, about 10× slower than float32."""


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
    precision: str = "auto"
    """The forward pass's arithmetic (``autocast_dtype``): ``auto``, ``float32`` or ``bfloat16``."""
    extra_data: tuple[str, ...] = ()
    """Further dataset folders: their training splits are appended to ``data``'s (each view once an epoch,
    each dataset augmented with its own seed); the held-out evaluation stays on ``data``'s test split."""
    init: str = ""
    """A checkpoint whose weights the run starts from instead of the seed's random initialisation
    (fine-tuning). It must hold the same variant, scale anchor and ``[network]``; its identity (path,
    SHA-256, epochs, wall time, data) goes into the run's checkpoints and model card. Empty: no init."""
    heatmap_radius: int = 1
    """The heatmap target's Gaussian, (2r+1)² output cells (``model.targets.render_heatmap``): 1 is the
    reference's 3×3; 2 at output stride 2 covers about the image area of 1 at stride 4."""
    channels_last: bool = False
    """Weights and inputs in the channels-last memory format (``KGNNet.use_channels_last``): the same network
    and loss, other kernels; with bfloat16 on the CPU about 1.2× the samples/s (``results/perf.md``)."""


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


def load_train_config(path: Path, settings: list[tuple[str, str]] = ()) -> TrainConfig:
    """Parse and validate a training TOML file, with ``settings`` (``(section.name, value)``, e.g.
    ``("train.epochs", "2")``) set over it (``config.override_tables``); ``TrainConfigError`` (one line) on
    any problem. A resumed run needs the same settings: they are part of the config it compares."""
    path = resolve_task(path)
    raw = override_tables(read_toml(path, "training config", TrainConfigError), list(settings), str(path),
                          TrainConfigError)
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
    if not 1 <= t.heatmap_radius <= 4:
        raise TrainConfigError(f"{path}: [train] heatmap_radius must be 1 to 4, got {t.heatmap_radius}")
    if t.precision not in PRECISIONS:
        raise TrainConfigError(f"{path}: unknown [train] precision {t.precision!r} (known: {', '.join(PRECISIONS)})")
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


def autocast_dtype(device: torch.device, precision: str = "auto", flags: frozenset[str] | None = None
                   ) -> torch.dtype | None:
    """The autocast type of a training step (None = plain float32); the weights and the optimiser stay float32.

    ``float32``: None; ``bfloat16``: bfloat16 on any device; ``auto``: bfloat16 on CUDA, and on a CPU whose
    ``flags`` (default this one's) include native bfloat16 instructions when the kernels are native
    (``KGN_BENCH_KERNELS=native``: the portable set caps oneDNN at AVX2, where bfloat16 is emulated); float32
    otherwise. On a Zen 4 core, bfloat16 with native kernels takes a KGNv2 training step in about half the
    time of float32 with the portable kernels (``results/perf.md``)."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, got {precision!r}")
    if precision == "float32":
        return None
    if precision == "bfloat16" or device.type == "cuda":
        return torch.bfloat16
    flags = cpu_flags() if flags is None else flags
    return torch.bfloat16 if device.type == "cpu" and kernels_mode() == "native" and BF16_FLAGS & flags else None


def bfloat16_emulated(device: torch.device, precision: str, flags: frozenset[str] | None = None) -> bool:
    """Whether ``precision`` asks for bfloat16 on a CPU that would emulate it: ``bfloat16`` on a CPU whose
    ``flags`` (default this one's) lack native bfloat16 instructions, or whose kernels are capped at AVX2
    (``KGN_BENCH_KERNELS`` not ``native``). oneDNN then takes a step many times longer than float32 (a KGNv2
    step: about 8 s against 0.5 s, ``results/perf.md``); ``auto`` would pick float32 there."""
    if precision != "bfloat16" or device.type != "cpu":
        return False
    flags = cpu_flags() if flags is None else flags
    return not (kernels_mode() == "native" and BF16_FLAGS & flags)


def train_step(net: KGNNet, optim: torch.optim.Optimizer, x: torch.Tensor, targets: dict[str, torch.Tensor],
               variant: Variant, weights: LossWeights, dtype: torch.dtype | None) -> dict[str, float]:
    """One optimisation step on a batch (on the network's device): the forward pass under autocast to ``dtype``
    (None: float32), the loss in float32 (``model.losses.kgn_loss``), backward, the optimiser's step. Returns
    the loss terms. ``kgn-bench perf train`` times this same function."""
    with torch.autocast(x.device.type, dtype=dtype or torch.bfloat16, enabled=dtype is not None):
        outputs = net(x)
    loss, parts = kgn_loss({k: v.float() for k, v in outputs.items()}, targets, variant, weights)
    optim.zero_grad(set_to_none=True)
    loss.backward()
    optim.step()
    return parts


def _collate(batch):
    xs, targets = zip(*batch)
    return torch.stack(xs), {k: torch.stack([t[k] for t in targets]) for k in targets[0]}


def _lr_at(cfg: TrainSettings, epoch: int) -> float:
    return cfg.lr * cfg.lr_gamma ** sum(epoch >= s for s in cfg.lr_steps)


HeldOutEvaluator = Callable[[LoadedModel, Path, int], dict[str, Any]]
"""``evaluate(model, data, views)``: the held-out metrics of ``model`` (the network being trained, in eval
mode, with its variant and configs) on the first ``views`` test views of the dataset ``data``, as the summary
dict of ``eval.vision.VisionMetrics.summarise`` (``thresholds``: one row per threshold with ``label``,
``gsr``, ``gcr``, ``osr``; ``images``: the views evaluated). ``eval.vision.held_out_evaluator`` is the one
the ``train`` command passes."""


@dataclass
class _Run:
    """One call of ``train``: the run folder ``out``, the dataset, the network and optimiser on ``device``,
    and the epochs completed so far (``start``, ``history``; restored from ``last.pt`` on resume)."""

    cfg: TrainConfig
    out: Path
    data: Path
    variant: Variant
    device: torch.device
    loader_workers: int
    dataset: GraspViewDataset | _Mixture
    identity: dict[str, Any]
    net: KGNNet
    optim: torch.optim.Optimizer
    commit: str
    init: dict[str, Any] | None = None
    start: int = 0
    history: list[dict[str, Any]] = field(default_factory=list)

    def payload(self, epoch: int, with_optimizer: bool) -> dict[str, Any]:
        """The checkpoint dict after ``epoch`` completed epochs (with the optimiser and torch RNG states for
        ``last.pt``, without them for ``final.pt``)."""
        cfg, net = self.cfg, self.net
        p = {
            **model_payload(net, self.variant.name, cfg.network, cfg.input, self.variant.scale_anchor),
            "train": cfg.to_dict(),
            "dataset": self.identity,
            "git_commit": self.commit,
            "epoch": epoch,
            "history": self.history,
            "parameters": count_parameters(net),
            "machine": machine_label(self.device),
            "precision": str(autocast_dtype(self.device, cfg.train.precision) or torch.float32).removeprefix("torch."),
            **({"init": self.init} if self.init else {}),
        }
        if with_optimizer:
            p["optimizer"] = self.optim.state_dict()
            p["torch_rng"] = torch.get_rng_state()
        return p


def _start_run(cfg: TrainConfig, device: str | None, threads: int | None) -> _Run:
    """Create the run folder, pick the device and threads, seed torch with ``[train] seed``, then build the
    dataset, the network and the optimiser in that order (so the initial weights depend on the seed only)."""
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

    roots = [data, *(Path(d) for d in t_cfg.extra_data)]
    parts = [GraspViewDataset(root, "train", variant, cfg.input, cfg.augment, seed=t_cfg.seed + 7919 * k,
                              limit=t_cfg.limit or None, assignment=t_cfg.assignment,
                              stride=cfg.network.output_stride, heatmap_radius=t_cfg.heatmap_radius)
             for k, root in enumerate(roots)]
    dataset = parts[0] if len(parts) == 1 else _Mixture(parts)
    if len(dataset) < t_cfg.batch_size:
        raise DatasetError(f"{data}: {len(dataset)} training views, fewer than one batch of {t_cfg.batch_size}")
    identity = _data_identity(roots)
    for root, ident in zip(roots, [identity, *identity.get("extra", [])]):
        leaks = test_set_leaks(ident["manifest"].get("object_types", []))
        if leaks:
            raise DatasetError(f"{root}: its scenes hold real test objects ({', '.join(leaks[:5])}); "
                               "never train on them")
    net = build_network(variant, cfg.network).to(dev).use_channels_last(t_cfg.channels_last)
    init = _load_init(net, cfg, variant) if t_cfg.init else None
    optim = torch.optim.Adam(net.parameters(), lr=t_cfg.lr)
    commit = git_commit()  # the code that starts the run (kept across resumes)
    return _Run(cfg, out, data, variant, dev, loader_workers, dataset, identity, net, optim, commit, init)


class _Mixture(ConcatDataset):
    """The training splits of several datasets as one (``[train] extra_data``); ``set_epoch`` reaches each."""

    def set_epoch(self, epoch: int) -> None:
        for part in self.datasets:
            part.set_epoch(epoch)


def _data_identity(roots: list[Path]) -> dict[str, Any]:
    """``dataset_identity`` of the first root; with more roots, theirs under ``extra`` and a ``sha256`` over
    all of them in order (what a resume compares)."""
    first = dataset_identity(roots[0])
    if len(roots) == 1:
        return first
    extra = [dataset_identity(r) for r in roots[1:]]
    combined = hashlib.sha256("".join(d["sha256"] for d in [first, *extra]).encode()).hexdigest()
    return {**first, "sha256": combined, "extra": extra}


def _load_init(net: KGNNet, cfg: TrainConfig, variant: Variant) -> dict[str, Any]:
    """Load ``[train] init``'s weights into ``net`` (``CheckpointError`` if the checkpoint holds another
    variant, scale anchor or network) and return its identity for the run's checkpoints: path, SHA-256 of
    the file, its completed epochs, its wall time in seconds and its dataset's path and SHA-256."""
    path = Path(cfg.train.init)
    try:
        ckpt = load_checkpoint(path)
    except CheckpointError as e:
        raise CheckpointError(f"[train] init: {e}") from None
    if ckpt["variant"] != variant.name or ckpt.get("scale_anchor", "none") != variant.scale_anchor:
        raise CheckpointError(f"{path}: [train] init holds {ckpt['variant']!r} weights (scale anchor "
                              f"{ckpt.get('scale_anchor', 'none')!r}); this run trains {variant.name!r} "
                              f"(scale anchor {variant.scale_anchor!r})")
    if json.loads(json.dumps(ckpt["network"])) != cfg.to_dict()["network"]:
        raise CheckpointError(f"{path}: [train] init was trained with another [network] than this config's")
    net.load_state_dict(ckpt["model"])
    history = ckpt.get("history", [])
    ds = ckpt.get("dataset", {})
    return {"path": str(path), "sha256": file_sha256(path),
            "epochs": int(ckpt.get("epoch", 0)), "seconds": round(sum(h.get("seconds", 0.0) for h in history), 1),
            "data": ds.get("path", "?"), "data_sha256": ds.get("sha256", "")}


def _with_defaults(stored: Any) -> Any:
    """A checkpoint's config with the settings added since it was written at their defaults (a run started
    before a new setting existed resumes with the setting's default, which is what it trained with)."""
    if not isinstance(stored, dict):
        return stored
    defaults = TrainConfig(name=str(stored.get("name", ""))).to_dict()
    return {k: {**defaults[k], **v} if isinstance(v, dict) and isinstance(defaults.get(k), dict) else v
            for k, v in {**defaults, **stored}.items()}


def _resume(run: _Run) -> None:
    """Continue from ``last.pt`` if the run folder has one: weights, optimiser, completed epochs, history,
    the starting commit and torch's RNG state. A checkpoint of another config or dataset is refused."""
    last = run.out / "last.pt"
    if not last.exists():
        return
    ckpt = load_checkpoint(last)
    if _with_defaults(ckpt.get("train")) != run.cfg.to_dict():
        raise CheckpointError(f"{last} was written by a different config; use another [train] out or delete it")
    if ckpt.get("dataset", {}).get("sha256") != run.identity["sha256"]:
        raise CheckpointError(f"{last} was trained on another dataset than {run.data}")
    if (ckpt.get("init") or {}).get("sha256") != (run.init or {}).get("sha256"):
        raise CheckpointError(f"{last} started from other weights than [train] init {run.cfg.train.init} holds now")
    run.net.load_state_dict(ckpt["model"])
    run.optim.load_state_dict(ckpt["optimizer"])
    run.start, run.history = int(ckpt["epoch"]), list(ckpt.get("history", []))
    run.commit = ckpt.get("git_commit", run.commit)
    torch.set_rng_state(ckpt["torch_rng"])


def _train_epoch(run: _Run, epoch: int, progress: bool) -> dict[str, Any]:
    """One pass over the shuffled training split (0-based ``epoch``) at the epoch's learning rate
    ``lr · γ^#{steps ≤ epoch}``; returns the history row: epoch (1-based), lr, seconds and the mean of each
    loss term over the batches."""
    t_cfg, dev = run.cfg.train, run.device
    cuda = dev.type == "cuda"
    dtype = autocast_dtype(dev, t_cfg.precision)
    run.dataset.set_epoch(epoch)
    for group in run.optim.param_groups:
        group["lr"] = _lr_at(t_cfg, epoch)
    loader = DataLoader(run.dataset, batch_size=t_cfg.batch_size, shuffle=True, drop_last=True,
                        num_workers=run.loader_workers, collate_fn=_collate, persistent_workers=False,
                        pin_memory=cuda, generator=torch.Generator().manual_seed(t_cfg.seed * 1000 + epoch),
                        worker_init_fn=loader_worker_init)
    bar = Progress(len(loader), f"epoch {epoch + 1}/{t_cfg.epochs}", unit="batch", enabled=progress)
    sums: dict[str, float] = {}
    t0 = time.perf_counter()
    for x, targets in loader:
        x = x.to(dev, non_blocking=cuda)
        targets = {k: v.to(dev, non_blocking=cuda) for k, v in targets.items()}
        parts = train_step(run.net, run.optim, x, targets, run.variant, run.cfg.loss, dtype)
        if not math.isfinite(parts["total"]):
            raise FloatingPointError(f"loss became {parts['total']} in epoch {epoch + 1}; lower [train] lr")
        for k, v in parts.items():
            sums[k] = sums.get(k, 0.0) + v
        bar.update(1, " ".join(f"{k} {v:.3f}" for k, v in parts.items()))
    row: dict[str, Any] = {"epoch": epoch + 1, "lr": _lr_at(t_cfg, epoch),
                           "seconds": round(time.perf_counter() - t0, 1)}
    row.update({k: round(v / max(len(loader), 1), 5) for k, v in sums.items()})
    return row


def _evaluate(run: _Run, evaluate: HeldOutEvaluator) -> dict[str, Any]:
    """The history entries of a held-out evaluation of the current weights: ``eval`` (GSR/GCR/OSR per
    threshold label) and ``eval_views``. The network is in eval mode during the call, in training mode after."""
    cfg = run.cfg
    run.net.eval()
    summary = evaluate(LoadedModel(run.net, run.variant, cfg.network, cfg.input, {}), run.data, cfg.train.eval_views)
    run.net.train()
    return {"eval": {t["label"]: {k: t[k] for k in ("gsr", "gcr", "osr")} for t in summary["thresholds"]},
            "eval_views": summary["images"]}


def train(cfg: TrainConfig, progress: bool = True, device: str | None = None, threads: int | None = None,
          evaluate: HeldOutEvaluator | None = None) -> Path:
    """Train (or resume) the run ``cfg.train.out``; returns the path of ``final.pt``.

    After every ``eval_every``-th epoch and the last one, ``evaluate`` (if given; see ``HeldOutEvaluator``)
    scores the weights on ``eval_views`` test views and the epoch's history row keeps the result; without
    it no epoch is evaluated. On the CPU, ``threads`` (default: torch's) sets the intra-op threads. The
    forward pass runs under ``autocast_dtype(device, [train] precision)``: with ``auto``, bfloat16 on CUDA and
    on CPUs with native bfloat16 and native kernels. On CUDA at least ``min(8, cores − 1)`` data-loading
    processes run; neither changes what a sample is, since augmentation is seeded per (seed, epoch, item).
    """
    t_cfg = cfg.train
    run = _start_run(cfg, device, threads)
    if bfloat16_emulated(run.device, t_cfg.precision):
        warn(f"{t_cfg.out}: precision = 'bfloat16' on a CPU without native bfloat16 (or with the portable "
             "kernels): oneDNN emulates it and a step takes many times longer; precision = 'auto' picks float32 here")
    _resume(run)
    run.net.train()
    for epoch in range(run.start, t_cfg.epochs):
        row = _train_epoch(run, epoch, progress)
        done = epoch + 1
        if evaluate is not None and ((t_cfg.eval_every and done % t_cfg.eval_every == 0) or done == t_cfg.epochs):
            row.update(_evaluate(run, evaluate))
        run.history.append(row)
        with (run.out / "history.jsonl").open("a") as f:
            f.write(json.dumps(row) + "\n")
        save_checkpoint(run.out / "last.pt", run.payload(done, with_optimizer=True))
        if progress:
            print(f"epoch {done}: " + " ".join(f"{k} {row[k]}" for k in ("total", "hm", "kpts", "width", "scale")
                                               if k in row), flush=True)
    final = run.out / "final.pt"
    save_checkpoint(final, run.payload(t_cfg.epochs, with_optimizer=False))
    return final
