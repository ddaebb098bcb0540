"""``kgn-bench study`` and ``kgn-bench experiment``: synthetic studies and the paper's
dataset tables."""

from __future__ import annotations

from pathlib import Path

from .common import writable
from .options import Parser, int_at_least

__all__ = ["add"]


def add(sub) -> None:
    """The ``study`` command group and ``experiment``."""
    st = sub.add_parser("study", help="synthetic studies")
    ssub = st.add_subparsers(dest="study_command", required=True, parser_class=Parser)
    _add_pnp_noise(ssub)
    _add_experiment(sub)


def _add_pnp_noise(ssub) -> None:
    """``kgn-bench study pnp-noise``: its arguments."""
    pn = ssub.add_parser("pnp-noise", help="the paper's Fig. 2: IPPE pose error vs distance under keypoint noise")
    pn.add_argument("--samples", type=int_at_least(1), default=2000, help="orientations per cell (default 2000)")
    pn.add_argument("--sigmas", type=float, nargs="+", default=[1.0, 2.0, 4.0], help="noise levels px (default 1 2 4)")
    pn.add_argument("--seed", type=int_at_least(0), default=0)
    pn.add_argument("--out", type=Path, default=Path("results/pnp_noise"), help="writes OUT.csv and OUT.png")
    pn.set_defaults(func=_cmd_study_pnp_noise)


def _cmd_study_pnp_noise(args) -> int:
    from kgn_bench.eval.pnp_noise import PnpNoiseConfig, run_pnp_noise, write_pnp_noise

    config = PnpNoiseConfig(samples=args.samples, seed=args.seed, sigmas=tuple(args.sigmas))
    writable(args.out.parent if str(args.out.parent) else Path("."), "study folder")
    rows = run_pnp_noise(config)
    print(f"{'box':<17} {'sigma':>5} {'d (m)':>6} {'rot mean':>9} {'rot med':>8} {'t mean':>8} {'t med':>7}  (deg, cm)")
    for r in rows:
        print(f"{r.box:<17} {r.sigma_px:>5g} {r.distance_m:>6.2f} {r.rot_mean_deg:>9.2f} {r.rot_median_deg:>8.2f} "
              f"{r.trans_mean_cm:>8.2f} {r.trans_median_cm:>7.2f}")
    paths = write_pnp_noise(rows, args.out)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


def _add_experiment(sub) -> None:
    """``kgn-bench experiment``: its arguments."""
    exp = sub.add_parser("experiment", help="the paper's dataset tables from trained weights (no retraining)")
    exp.add_argument("table", choices=("table1", "table2"),
                     help="table1: KGN vs KGNv2, single/multi x single/multi; table2: the ablation")
    exp.add_argument("--single", type=Path, default=Path("data/ps_single"), help="single-object PS dataset")
    exp.add_argument("--multi", type=Path, default=Path("data/ps_multi"), help="multi-object PS dataset")
    exp.add_argument("--views", type=int_at_least(1), help="evaluate only the first N test views (default all)")
    exp.add_argument("--out", type=Path, default=Path("results"), help="results folder (default results)")
    exp.add_argument("--partial", action="store_true", help="build the table from the models that exist")
    exp.add_argument("--force", action="store_true", help="re-evaluate even when a cached evaluation matches")
    exp.set_defaults(func=_cmd_experiment)


def _cmd_experiment(args) -> int:
    from kgn_bench.eval.experiments import build_table1, build_table2

    build = {"table1": build_table1, "table2": build_table2}[args.table]
    data_dirs = {"single": args.single, "multi": args.multi}
    writable(args.out, "results folder")
    text, _ = build(data_dirs, args.out, views=args.views, partial=args.partial, force=args.force)
    print(text)
    print(f"wrote {args.out}/vision_{args.table}.md, .json (per-model evaluations in {args.out}/vision/)")
    return 0
