"""``kgn-bench train`` and ``kgn-bench ship``: train a model, ship its checkpoint as weights."""

from __future__ import annotations

from pathlib import Path

from .common import setting_pairs, writable
from .options import int_at_least, parent, quiet_option

__all__ = ["add"]


def add(sub) -> None:
    """The ``train`` and ``ship`` commands."""
    for add_command in (_add_train, _add_ship):
        add_command(sub)


def _add_train(sub) -> None:
    """``kgn-bench train``: its arguments."""
    tr = sub.add_parser("train", help="train a KGN / KGNv2 model, or VGN, from a config (resumes an interrupted "
                                      "run)", parents=[parent(quiet_option)])
    tr.add_argument("config", type=Path, help="training config: tasks/train_*.toml (or its bundled name) for KGN, a "
                                              "file with a [vgn] section (tasks/vgn_train.toml) for VGN")
    tr.add_argument("--device", help="torch device (default: cuda when present, else cpu)")
    tr.add_argument("--threads", type=int_at_least(1), help="CPU threads for torch (default: all cores)")
    tr.add_argument("--set", action="append", metavar="SECTION.NAME=VALUE",
                    help="override one setting of the config, e.g. train.epochs=2 or vgn.data=data/vgn "
                         "(repeatable; a resumed run needs the same ones)")
    tr.set_defaults(func=_cmd_train)


def _settings(values: list[str] | None) -> list[tuple[str, str]]:
    from kgn_bench.training.train import TrainConfigError

    return setting_pairs(values, TrainConfigError)


def _cmd_train(args) -> int:
    from kgn_bench.config import read_toml, resolve_task
    from kgn_bench.eval.vision import held_out_evaluator
    from kgn_bench.training.train import TrainConfigError, load_train_config, train

    path = resolve_task(args.config) if not Path(args.config).is_file() else Path(args.config)
    if "vgn" in read_toml(path, "training config", TrainConfigError):
        return _train_vgn(path, args)
    cfg = load_train_config(args.config, _settings(args.set))
    writable(Path(cfg.train.out), "training run folder")
    final = train(cfg, progress=not args.quiet, device=args.device, threads=args.threads, evaluate=held_out_evaluator)
    print(f"wrote {final}")
    return 0


def _train_vgn(path: Path, args) -> int:
    from kgn_bench.training.vgn_train import VGNTrainConfigError, load_vgn_train_config, train_vgn

    cfg = load_vgn_train_config(path, _settings(args.set))
    if not cfg.out:
        raise VGNTrainConfigError(f"{path} [vgn]: out must name the run folder")
    writable(Path(cfg.out), "training run folder")
    final = train_vgn(cfg, Path(cfg.out), threads=args.threads, device=args.device, progress=not args.quiet)
    print(f"wrote {final}")
    return 0


def _add_ship(sub) -> None:
    """``kgn-bench ship``: its arguments."""
    ex = sub.add_parser("ship", help="ship a trained checkpoint as weights with a model card")
    ex.add_argument("checkpoint", type=Path, help="a training run's final.pt (or last.pt), KGN's or VGN's")
    ex.add_argument("--name", required=True, help="weights name (kgnv2, kgn, vgn, ...)")
    ex.add_argument("--out", type=Path, default=Path("assets/weights"),
                    help="folder (default assets/weights: the shipped weights, run from the repository)")
    ex.set_defaults(func=_cmd_ship)


def _cmd_ship(args) -> int:
    from kgn_bench.model.checkpoint import checkpoint_format, export_weights
    from kgn_bench.model.vgn_checkpoint import VGN_FORMAT, export_vgn_weights
    from kgn_bench.viz.figures import save_training_curves

    writable(args.out, "weights folder")
    if checkpoint_format(args.checkpoint) == VGN_FORMAT:  # anything else: export_weights names the problem
        weights, card = export_vgn_weights(args.checkpoint, args.name, args.out)
    else:
        weights, card = export_weights(args.checkpoint, args.name, args.out)
    save_training_curves(weights)
    print(f"wrote {weights} ({weights.stat().st_size / 1e6:.1f} MB) and {card}")
    return 0
