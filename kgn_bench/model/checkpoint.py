"""Checkpoints and shipped weights: one ``.pt`` file holding everything needed to rebuild the detector.

A checkpoint is a ``torch.save`` dict:

``format`` ("kgn-bench-checkpoint"), ``version``, ``variant`` (the training variant's name),
``network`` and ``input`` (the ``NetworkConfig`` / ``InputConfig`` fields), ``model`` (state dict),
``train`` (the training config as a dict), ``dataset`` (the dataset manifest and its SHA-256; with
``extra`` datasets, theirs too and a SHA-256 over all), ``init`` (only in a fine-tuned run: the identity of
the checkpoint it started from),
``git_commit``, ``epoch`` (completed epochs), ``history`` (per-epoch losses and metrics), and, in
training checkpoints only, ``optimizer`` and ``scheduler`` states (stripped from shipped weights).

Files are written atomically (temporary file, fsync, rename), so an interrupted save never leaves a
truncated checkpoint under the final name. Loading checks the format, the variant and the tensor shapes
and fails with one ``CheckpointError`` line naming the problem.
"""

from __future__ import annotations

import hashlib
import json
import re
import subprocess
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

import torch

from kgn_bench.errors import KGNBenchError
from kgn_bench.io import atomic_write, atomic_write_text
from kgn_bench.model.network import KGNNet, NetworkConfig, build_network
from kgn_bench.model.preprocess import InputConfig
from kgn_bench.model.variants import VARIANTS, Variant, get_variant

__all__ = [
    "FORMAT",
    "VERSION",
    "CheckpointError",
    "LoadedModel",
    "checkpoint_format",
    "dataset_identity",
    "export_weights",
    "git_commit",
    "load_checkpoint",
    "load_model",
    "model_card",
    "model_payload",
    "save_checkpoint",
]

FORMAT = "kgn-bench-checkpoint"
VERSION = 1


class CheckpointError(KGNBenchError, ValueError):
    """A checkpoint file is missing, corrupt, of another format or of another variant."""


def git_commit(repo: Path | None = None) -> str:
    """The current commit of the source tree (``+dirty`` if modified), or ``unknown``."""
    cwd = repo or Path(__file__).resolve().parents[2]
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True, timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=cwd,
                               capture_output=True, text=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return "unknown"
    if sha.returncode != 0:
        return "unknown"
    return sha.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def dataset_identity(root: Path) -> dict[str, Any]:
    """The dataset's manifest and the SHA-256 of its manifest and split files (what a model was trained on)."""
    root = Path(root)
    h = hashlib.sha256()
    for name in ("dataset.json", "train.txt", "test.txt"):
        p = root / name
        if p.is_file():
            h.update(name.encode() + b"\0" + p.read_bytes())
    manifest = json.loads((root / "dataset.json").read_text()) if (root / "dataset.json").is_file() else {}
    return {"path": str(root), "sha256": h.hexdigest(), "manifest": manifest}


def save_checkpoint(path: Path, payload: dict[str, Any]) -> None:
    """Atomically write ``payload`` (completed with ``format`` and ``version``) to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = {"format": FORMAT, "version": VERSION, **payload}
    atomic_write(path, lambda f: torch.save(data, f))


_CARD_SHA = re.compile(r"^\| sha256 \| `([0-9a-f]{64})` \|$", re.MULTILINE)


def file_sha256(path: Path) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def card_sha256(weights: Path) -> str | None:
    """The SHA-256 recorded in the model card beside ``weights`` (``<name>.md``), None without one."""
    card = Path(weights).with_suffix(".md")
    if not card.is_file():
        return None
    found = _CARD_SHA.search(card.read_text(errors="replace"))
    return found.group(1) if found else None


def verify_weights(path: Path) -> None:
    """Check a weights file against the SHA-256 of its model card; ``CheckpointError`` on a mismatch. Files
    without a card (a training run's checkpoints, one's own exports elsewhere) are not checked."""
    expected = card_sha256(path)
    if expected is not None and file_sha256(path) != expected:
        raise CheckpointError(f"{path}: SHA-256 differs from its model card {Path(path).with_suffix('.md').name} "
                              "(damaged or replaced file; restore it, or re-export it to write a new card)")


def checkpoint_format(path: Path) -> str | None:
    """The ``format`` entry of the checkpoint dict at ``path`` (``FORMAT`` for KGN's, VGN's own for VGN's), or
    None for a file that is not a readable checkpoint dict. Loaded with ``weights_only=True``: a checkpoint is
    data, and a file that would run code on loading is not readable here."""
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception:  # torch raises many types for a damaged or hostile file
        return None
    return data.get("format") if isinstance(data, dict) else None


def read_checkpoint(path: Path, fmt: str, version: int, required: tuple[str, ...], what: str = "checkpoint",
                    missing: str | None = None) -> dict[str, Any]:
    """The dict a checkpoint file of format ``fmt`` and ``version`` holds, with every key of ``required``;
    ``CheckpointError`` (one line naming the file, calling it a ``what``) if it is missing (``missing``: that
    message instead), differs from its model card's SHA-256 (``verify_weights``), is unreadable, of another
    format or version, or lacks a key."""
    path = Path(path)
    if not path.is_file():
        raise CheckpointError(missing or f"no {what} at {path}")
    verify_weights(path)
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises many types for a damaged file
        raise CheckpointError(f"{path}: not a readable {what} ({type(e).__name__})") from None
    if not isinstance(data, dict) or data.get("format") != fmt:
        raise CheckpointError(f"{path}: not a kgn-bench {what}")
    if data.get("version") != version:
        raise CheckpointError(f"{path}: {what} version {data.get('version')}, expected {version}")
    for key in required:
        if key not in data:
            raise CheckpointError(f"{path}: {what} lacks {key!r}")
    return data


def load_checkpoint(path: Path) -> dict[str, Any]:
    """Read a checkpoint dict; ``CheckpointError`` if the file is missing, corrupt, not ours, or does not
    match the SHA-256 of its model card (``verify_weights``)."""
    return read_checkpoint(path, FORMAT, VERSION, ("variant", "network", "input", "model"))


def _config(cls, values: dict, path: Path):
    names = {f.name for f in fields(cls)}
    unknown = set(values) - names
    if unknown:
        raise CheckpointError(f"{path}: unknown {cls.__name__} fields {sorted(unknown)}")
    try:
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})
    except (TypeError, ValueError) as e:
        raise CheckpointError(f"{path}: bad {cls.__name__}: {e}") from None


class LoadedModel:
    """A network in eval mode with the configs it was trained with."""

    def __init__(self, net: KGNNet, variant: Variant, network: NetworkConfig, input_config: InputConfig,
                 meta: dict[str, Any]) -> None:
        self.net, self.variant, self.network, self.input_config, self.meta = net, variant, network, input_config, meta


def load_model(path: Path, variant: Variant | None = None) -> LoadedModel:
    """Build the network a checkpoint describes and load its weights.

    ``variant``: the decoding variant the caller wants; its ``weights_variant`` must equal the
    checkpoint's training variant (``kgn_depth`` loads ``kgn`` weights), else ``CheckpointError``. The
    returned model's variant carries the checkpoint's ``scale_anchor`` (``"none"`` for checkpoints that
    predate it).
    """
    data = load_checkpoint(path)
    trained = data["variant"]
    anchor = data.get("scale_anchor", "none")
    try:
        trained_variant = get_variant(trained).with_scale_anchor(anchor)
    except ValueError as e:
        raise CheckpointError(f"{path}: {e}") from None
    if variant is not None and variant.weights_variant != trained:
        raise CheckpointError(
            f"{path} holds {trained!r} weights, but {variant.name!r} needs {variant.weights_variant!r} weights"
        )
    network = _config(NetworkConfig, data["network"], Path(path))
    input_config = _config(InputConfig, data["input"], Path(path))
    net = build_network(trained_variant, network)
    try:
        net.load_state_dict(data["model"])
    except (RuntimeError, KeyError, TypeError) as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise CheckpointError(f"{path}: weights do not fit the network ({first})") from None
    net.eval()
    meta = {k: v for k, v in data.items() if k not in ("model", "optimizer", "scheduler")}
    chosen = variant.with_scale_anchor(anchor) if variant is not None else trained_variant
    return LoadedModel(net, chosen, network, input_config, meta)


def config_dict(config) -> dict[str, Any]:
    """A dataclass config as a plain dict (tuples become lists), for checkpoints and cards."""
    return json.loads(json.dumps(asdict(config)))


def model_payload(net: torch.nn.Module, variant: str, network: NetworkConfig, input_config: InputConfig,
                  scale_anchor: str = "none") -> dict[str, Any]:
    """The checkpoint entries that rebuild a network: ``variant`` (the training variant's name),
    ``scale_anchor``, ``network``, ``input`` and ``model`` (the state dict on the CPU); ``load_model`` reads
    exactly these."""
    return {"variant": variant, "scale_anchor": scale_anchor, "network": config_dict(network),
            "input": config_dict(input_config), "model": {k: v.detach().cpu() for k, v in net.state_dict().items()}}


def model_card(data: dict[str, Any], name: str, size_bytes: int, sha256: str | None = None) -> str:
    """A Markdown model card from a checkpoint dict: variant, the weights file's SHA-256 (checked on every
    load), data, schedule, wall time, machine, commit, final losses and the last held-out metrics."""
    train = data.get("train", {}).get("train", {})
    history = data.get("history", [])
    last = history[-1] if history else {}
    evals = [h for h in history if isinstance(h.get("eval"), dict)]
    seconds = sum(h.get("seconds", 0.0) for h in history)
    ds = data.get("dataset", {})
    manifest = ds.get("manifest", {})
    init = data.get("init") or {}
    lines = [
        f"# {name}",
        "",
        "| field | value |",
        "| --- | --- |",
        f"| variant | `{data['variant']}`{_anchor_text(data)} |",
        *([f"| sha256 | `{sha256}` |"] if sha256 else []),
        f"| parameters | {data.get('parameters', 'n/a')} |",
        f"| file size | {size_bytes / 1e6:.1f} MB |",
        f"| data | `{ds.get('path', '?')}`: {manifest.get('mode', '?')}-object PS, "
        f"{manifest.get('scenes', '?')} scenes × {manifest.get('views', '?')} views, seed {manifest.get('seed', '?')} "
        f"(sha256 {str(ds.get('sha256', ''))[:12]}) |",
        *[f"| more data | `{x.get('path', '?')}`: {x.get('manifest', {}).get('mode', '?')}-object PS, "
          f"{x.get('manifest', {}).get('scenes', '?')} scenes × {x.get('manifest', {}).get('views', '?')} views "
          f"(sha256 {str(x.get('sha256', ''))[:12]}) |" for x in ds.get("extra", [])],
        *([f"| initialised from | `{init.get('path', '?')}` (sha256 {str(init.get('sha256', ''))[:12]}): "
           f"{init.get('epochs', '?')} epochs on `{init.get('data', '?')}`, {init.get('seconds', 0) / 60:.0f} min |"]
          if init else []),
        f"| epochs | {data.get('epoch', '?')} (batch {train.get('batch_size', '?')}, Adam lr {train.get('lr', '?')}, "
        f"×{train.get('lr_gamma', '?')} after epochs {train.get('lr_steps', '?')}) |",
        f"| training views | {train.get('limit') or 'all of the train split'} |",
        f"| wall time | {seconds / 60:.0f} min"
        + (f" ({(seconds + init.get('seconds', 0)) / 60:.0f} min with the initial weights' training)" if init else "")
        + " |",
        f"| machine | {data.get('machine', '?')}, {data.get('precision', 'float32')} forward pass |",
        f"| git commit | `{data.get('git_commit', '?')}` |",
        f"| config | `{data.get('train', {}).get('name', '?')}` |",
        f"| network | {json.dumps(data.get('network', {}))} |",
        f"| input | {json.dumps(data.get('input', {}))} |",
    ]
    if last:
        losses = ", ".join(f"{k} {last[k]:.4f}" for k in ("total", "hm", "reg", "kpts", "width", "scale") if k in last)
        lines += [f"| final losses (epoch {last.get('epoch')}) | {losses} |"]
    if evals:
        e = evals[-1]
        figs = "; ".join(f"{label}: GSR {_pct(v['gsr'])} GCR {_pct(v['gcr'])} OSR {_pct(v['osr'])}"
                         for label, v in e["eval"].items())
        lines += [f"| held-out check (epoch {e['epoch']}, {e.get('eval_views', '?')} test views) | {figs} |"]
    lines += ["", f"![training curves]({name}_training.png)"] if history else []
    lines += ["", "Training curve (per epoch): " + ", ".join(f"{h['epoch']}: {h.get('total', float('nan')):.3f}"
                                                         for h in history)]
    return "\n".join(lines) + "\n"


def _anchor_text(data: dict[str, Any]) -> str:
    """How the card names the scale head's parameterisation ("" for a variant without one)."""
    if data.get("variant") not in VARIANTS or not VARIANTS[data["variant"]].scale_branch:
        return ""
    if data.get("scale_anchor", "none") == "depth":
        return ", scale head: residual to the observed depth along the ray"
    return ", scale head: absolute distance"


def _pct(x: float | None) -> str:
    return "n/a" if x is None else f"{100 * x:.1f} %"


def export_weights(src: Path, name: str, out_dir: Path) -> tuple[Path, Path]:
    """Copy a checkpoint's weights (no optimizer state) to ``out_dir/<name>.pt`` and write the model card
    ``out_dir/<name>.md``; returns the weights and card paths. The card shows the training curves
    ``out_dir/<name>_training.png``, which ``viz.figures.save_training_curves(weights)`` draws (the model
    layer draws nothing)."""
    data = load_checkpoint(src)
    slim = {k: v for k, v in data.items() if k not in ("optimizer", "torch_rng", "format", "version")}
    slim["model"] = {k: v.to(torch.float32) if v.is_floating_point() else v for k, v in slim["model"].items()}
    out_dir = Path(out_dir)
    weights = out_dir / f"{name}.pt"
    save_checkpoint(weights, slim)
    card = out_dir / f"{name}.md"
    atomic_write_text(card, model_card(data, name, weights.stat().st_size, file_sha256(weights)))
    return weights, card
