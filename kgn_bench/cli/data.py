"""``kgn-bench data``: generate and draw the Primitive Shape dataset; generate VGN's."""

from __future__ import annotations

from pathlib import Path

from .common import fail, make_backend, warn, writable, writable_file
from .options import Parser, cluster_options, int_at_least, parent, quiet_option, workers_option

__all__ = ["add"]


def add(sub) -> None:
    """The ``data`` command group."""
    data = sub.add_parser("data", help="the Primitive Shape dataset, and VGN's training data")
    dsub = data.add_subparsers(dest="data_command", required=True, parser_class=Parser)
    for add_command in (_add_generate, _add_show, _add_vgn):
        add_command(dsub)


def _object_groups(items: list[str], workers: int = 1) -> list[list[str]]:
    """Object names from the command line, one list per argument: ``primitives`` and ``household`` expand to the
    built-in groups, a packaged set's name (``pybullet_test``, ``pybullet_train:300``) to its objects; the
    packaged ones the library lacks are imported first. An object of a set that the importer refuses (a broken
    mesh) is left out with a warning naming it and why; one named on its own is an error. A name already in an
    earlier argument's list is dropped from later ones; empty lists are dropped. Imports run on ``workers``
    processes."""
    from kgn_bench.objects.pybullet_set import ensure_objects
    from kgn_bench.shapes import OBJECTS, PRIMITIVES, is_known
    from kgn_bench.shapes.library import is_set_name, packaged, set_names
    from kgn_bench.shapes.mesh_object import ObjectError

    builtin = {"primitives": list(PRIMITIVES), "household": [n for n in OBJECTS if n not in PRIMITIVES]}
    groups: list[list[str]] = []
    from_sets: set[str] = set()
    for item in items:
        if item in builtin:
            groups.append(builtin[item])
        elif is_set_name(item):
            groups.append(set_names(item))
            from_sets.update(groups[-1])
        else:
            groups.append([item])
    names = [n for g in groups for n in g]
    for n in names:
        if not (is_known(n) or packaged(n)):
            raise ObjectError(f"unknown object {n!r}: neither built in, imported nor in a packaged set "
                              "(kgn-bench objects list)")
    ensure_objects([n for n in names if n not in from_sets], workers=workers)
    refused = ensure_objects([n for n in names if n in from_sets], workers=workers, refusals=True)
    if refused:
        warn(f"{len(refused)} object(s) of the set(s) could not be imported and are left out: "
             + "; ".join(f"{name} ({reason})" for name, reason in sorted(refused.items())))
    seen: set[str] = set()
    kept = []
    for g in groups:
        g = [n for n in dict.fromkeys(g) if n not in refused and n not in seen]
        seen.update(g)
        if g:
            kept.append(g)
    return kept


def _object_names(items: list[str], workers: int = 1) -> list[str]:
    """``_object_groups`` as one list of names, in order."""
    return [n for g in _object_groups(items, workers) for n in g]


def _add_generate(dsub) -> None:
    """``kgn-bench data generate``: its arguments."""
    gen = dsub.add_parser("generate", help="generate a PS dataset (resumes an interrupted run)",
                          parents=[parent(workers_option(1, cluster=True), cluster_options, quiet_option)])
    gen.add_argument("--mode", choices=("single", "multi"), required=True,
                     help="single: one random shape per scene; multi: one of each of the six shapes")
    gen.add_argument("--scenes", type=int_at_least(1), default=1000, help="number of scenes (default 1000)")
    gen.add_argument("--views", type=int_at_least(1), default=5, help="camera views per scene (default 5)")
    gen.add_argument("--seed", type=int_at_least(0), default=0, help="dataset seed (default 0)")
    gen.add_argument("--out", type=Path, required=True, help="output folder")
    gen.add_argument("--overwrite", action="store_true", help="replace a dataset with other settings in --out")
    gen.add_argument("--objects", nargs="+", metavar="NAME",
                     help="object types, groups (primitives, household) or a set (pybullet_test, "
                          "pybullet_train:300) to draw from instead of the six primitives; multi mode puts six of "
                          "them in each scene; with several arguments of which one is a group or set, each "
                          "argument is drawn equally often")
    gen.add_argument("--appearance", choices=("plain", "random"), default="plain",
                     help="plain: a uniform colour per object (the paper's data); random: procedural textures and "
                          "colours per object and for the table")
    gen.add_argument("--depth-noise", type=float, default=0.0, metavar="S",
                     help="strength of the benchmark camera's D435-like depth noise on the stored depth (default 0)")
    gen.set_defaults(func=_cmd_data_generate)


def _cmd_data_generate(args) -> int:
    from kgn_bench.data.generate import GenerateConfig, generate_dataset
    from kgn_bench.sim.scene import PhysicsError

    backend = make_backend(args)
    writable(args.out)
    groups = _object_groups(args.objects or [], args.workers if backend.kind == "local" else 1)
    objects = [n for g in groups for n in g]
    # each argument drawn equally often when one of several is a group or a set (GenerateConfig.groups)
    sizes = tuple(len(g) for g in groups) if len(groups) > 1 and max(map(len, groups)) > 1 else ()
    config = GenerateConfig(mode=args.mode, scenes=args.scenes, views=args.views, seed=args.seed,
                            objects=tuple(objects), groups=sizes, appearance=args.appearance,
                            depth_noise=args.depth_noise)
    try:
        stats = generate_dataset(config, args.out, workers=args.workers, overwrite=args.overwrite,
                                 progress=not args.quiet, backend=backend)
    except PhysicsError as e:
        return fail(f"{e}; finished scenes are kept, rerun the same command to resume")
    done = config.scenes - stats.scenes
    print(
        f"{args.out}: {config.scenes} scenes x {config.views} views ({stats.scenes} generated now"
        + (f", {done} already there" if done else "")
        + f") in {stats.wall:.1f} s, {stats.views_per_second:.1f} views/s"
    )
    return 0


def _add_show(dsub) -> None:
    """``kgn-bench data show``: its arguments."""
    show = dsub.add_parser("show", help="draw a view's collision-free ground-truth grasps and its depth")
    show.add_argument("dir", type=Path, help="dataset folder")
    show.add_argument("--scene", type=int_at_least(0), required=True)
    show.add_argument("--view", type=int_at_least(0), default=0)
    show.add_argument("--box", choices=("width", "fixed"), default="width",
                      help="keypoint box side: the grasp width (default) or the fixed 0.1 m training box")
    show.add_argument("--out", type=Path, required=True, help="PNG to write")
    show.set_defaults(func=_cmd_data_show)


def _cmd_data_show(args) -> int:
    from kgn_bench.viz.draw import show_view
    from kgn_bench.viz.images import save_png

    writable_file(args.out, "image")
    save_png(args.out, show_view(args.dir, args.scene, args.view, box=args.box))
    print(f"wrote {args.out}")
    return 0


VGN_OBJECTS = ("primitives", "pybullet_train:300")
"""The default training set of ``kgn-bench data vgn``: the six primitives and the eight household shapes."""


def _add_vgn(dsub) -> None:
    """``kgn-bench data vgn``: its arguments."""
    vgn = dsub.add_parser("vgn", help="generate VGN's training data: GIGA-style scenes, grasps labelled in physics "
                                      "with the floating Panda hand (resumes an interrupted run)",
                          parents=[parent(workers_option(1, cluster=True), cluster_options, quiet_option)])
    vgn.add_argument("--scenes", type=int_at_least(1), default=1000,
                     help="number of scenes, half piles, half packed (default 1000; a finished dataset grows when "
                          "rerun with more)")
    vgn.add_argument("--grasps", type=int_at_least(1), default=240, help="grasp positions per scene (default 240)")
    vgn.add_argument("--seed", type=int_at_least(0), default=0, help="dataset seed (default 0)")
    vgn.add_argument("--objects", nargs="+", metavar="NAME", default=list(VGN_OBJECTS),
                     help="object types, groups, imported objects or sets to draw from (default: primitives "
                          "pybullet_train:300, imported first if missing); never the real test set")
    vgn.add_argument("--out", type=Path, required=True, help="output folder")
    vgn.set_defaults(func=_cmd_data_vgn)


def _cmd_data_vgn(args) -> int:
    from kgn_bench.data.vgn_generate import VGNDataConfig, generate_vgn_dataset
    from kgn_bench.shapes.library import test_set_leaks

    backend = make_backend(args)
    objects = _object_names(args.objects, args.workers if backend.kind == "local" else 1)
    leaks = test_set_leaks(objects)
    if leaks:
        return fail(f"{', '.join(sorted(leaks))}: real test objects (by name or mesh) never go into training data")
    writable(args.out)
    config = VGNDataConfig(scenes=args.scenes, objects=tuple(objects), grasps_per_scene=args.grasps, seed=args.seed)
    stats = generate_vgn_dataset(config, args.out, workers=args.workers, progress=not args.quiet, backend=backend)
    print(f"{args.out}: {stats['scenes']} scenes generated now in {stats['wall_s']:.0f} s "
          f"({stats['scenes_per_hour']:.0f} scenes/h, {stats['grasps']} grasps); the dataset holds "
          f"{stats['total_grasps']} grasps, {stats['positives']} of them positive")
    return 0
