"""``kgn-bench objects``: import meshes as benchmark objects, list, draw and check them."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from .common import warn, writable_file
from .options import Parser, int_at_least, parent, quiet_option, workers_option

__all__ = ["add"]


def add(sub) -> None:
    """The ``objects`` command group."""
    obj = sub.add_parser("objects", help="import meshes as benchmark objects, list and draw them")
    osub = obj.add_subparsers(dest="objects_command", required=True, parser_class=Parser)
    for add_command in (_add_add, _add_list, _add_show, _add_import_set, _add_check_labeller):
        add_command(osub)


def _add_add(osub) -> None:
    """``kgn-bench objects add``: its arguments."""
    add = osub.add_parser("add", help="import a mesh (OBJ, STL, PLY, GLB): repair, CoACD hulls, verified grasps")
    add.add_argument("mesh", type=Path, help="mesh file")
    add.add_argument("--name", required=True, help="object name used by task files (lower case, digits, _ -)")
    add.add_argument("--scale", type=float, help="multiply the coordinates by this (e.g. 0.001 for mm)")
    add.add_argument("--size", type=float, help="scale so that the largest extent is this many metres")
    add.add_argument("--density", type=float, default=700.0, help="kg/m³ for the mass (default 700, as VGN)")
    add.add_argument("--mass", type=float, help="mass in kg (instead of density × volume)")
    add.add_argument("--color", type=float, nargs=3, default=(0.7, 0.55, 0.35), metavar=("R", "G", "B"))
    add.add_argument("--hulls", type=int_at_least(1), default=8, help="most convex pieces (CoACD; default 8)")
    add.add_argument("--verify", type=int_at_least(8), default=160,
                     help="grasp candidates checked in physics (default 160)")
    add.add_argument("--seed", type=int_at_least(0), default=0)
    add.add_argument("--licence", default="unknown", help="the mesh's licence, kept in the manifest")
    add.add_argument("--root", type=Path, help="object library to write to (default $KGN_BENCH_OBJECTS or "
                                               "~/.local/share/kgn-bench/objects)")
    add.add_argument("--overwrite", action="store_true", help="replace an object of the same name")
    add.set_defaults(func=_cmd_objects_add)


def _cmd_objects_add(args) -> int:
    from kgn_bench.objects.importer import ImportConfig, import_mesh
    from kgn_bench.shapes.library import packaged
    from kgn_bench.shapes.mesh_object import MeshObject

    config = ImportConfig(scale=args.scale, size=args.size, density=args.density, mass=args.mass,
                          color=tuple(args.color), hulls=args.hulls, seed=args.seed, verify=args.verify,
                          licence=args.licence)
    started = time.perf_counter()

    def progress(stage: str) -> None:
        sys.stderr.write(f"{args.name}: {stage} ({time.perf_counter() - started:.0f} s)\n")

    folder = import_mesh(args.mesh, args.name, config, root=args.root, overwrite=args.overwrite, progress=progress)
    if packaged(args.name):
        warn(f"{args.name} now shadows the packaged object of that name in every task that names it "
              "(remove the folder to undo)")
    m = MeshObject(folder).manifest
    if "remeshed" in m:
        r = m["remeshed"]
        warn(f"{args.name}: {r['reason']}; remeshed as a {r['pitch_m'] * 1000:.1f} mm voxel solid"
             f"{' (thin sheets thickened into walls)' if r['thickened'] else ''}: its surface lies within "
             f"{r['deviation_m'] * 1000:.1f} mm of the file's")
    g, t = m["grasps"], m["timing_s"]
    print(f"{m['name']}: {folder} ({m['faces']} faces, {m['hulls']} hulls, {m['mass'] * 1000:.0f} g, "
          f"{g['held']} of {g['checked']} checked grasps held, {t['total']:.1f} s)")
    return 0


def _add_list(osub) -> None:
    """``kgn-bench objects list``: its arguments."""
    ls = osub.add_parser("list", help="the built-in object types and the imported objects")
    ls.set_defaults(func=_cmd_objects_list)


def _cmd_objects_list(args) -> int:
    from kgn_bench.shapes import OBJECTS
    from kgn_bench.shapes.library import library_roots, list_objects
    from kgn_bench.shapes.mesh_object import MeshObject, ObjectError, check_object

    print("built-in: " + ", ".join(OBJECTS))
    found = list_objects()
    print(f"imported ({len(found)}; searched {', '.join(map(str, library_roots()))}):")
    broken = 0
    for name, folder in found.items():
        try:
            check_object(folder)
            m = MeshObject(folder).manifest
            ext = " x ".join(f"{e * 100:.1f}" for e in m["extents_m"])
            print(f"  {name:<16} {ext} cm  {m['mass'] * 1000:6.0f} g  {m['grasps']['held']:4d} grasps  {folder}")
        except (ObjectError, KeyError, TypeError) as e:  # one bad entry is marked, the others are listed
            broken += 1
            reason = str(e).splitlines()[0] if isinstance(e, ObjectError) else f"manifest lacks {e}"
            print(f"  {name:<16} BROKEN: {reason}")
    if broken:
        warn(f"{broken} imported object(s) are broken; import them again (kgn-bench objects add … --overwrite)")
    return 0


def _add_show(osub) -> None:
    """``kgn-bench objects show``: its arguments."""
    show = osub.add_parser("show", help="a PNG of an object with its grasps")
    show.add_argument("name")
    show.add_argument("--out", type=Path, required=True, help="PNG to write")
    show.add_argument("--grasps", type=int_at_least(1), default=30, help="grasps drawn (default 30)")
    show.add_argument("--seed", type=int_at_least(0), default=0, help="size draw of a built-in type")
    show.set_defaults(func=_cmd_objects_show)


def _cmd_objects_show(args) -> int:
    import numpy as np

    from kgn_bench.objects.coverage import REST_GRASPS, rest_pose_grasps
    from kgn_bench.shapes import sample_shape
    from kgn_bench.shapes.mesh_object import MeshObject
    from kgn_bench.viz.objects import draw_object

    writable_file(args.out, "image")
    shape = sample_shape(args.name, np.random.default_rng(args.seed))
    draw_object(shape, args.out, max_grasps=args.grasps)
    print(f"wrote {args.out}")
    if isinstance(shape, MeshObject):
        rests = rest_pose_grasps(shape)
        print(f"{args.name}: verified grasps the gripper can execute from above the table, per rest pose:")
        for k, (p, n) in enumerate(rests):
            print(f"  rest pose {k}: probability {p:.3f}, {n} grasps" + ("  (few)" if n < REST_GRASPS / 3 else ""))
    return 0


def _add_import_set(osub) -> None:
    """``kgn-bench objects import-set``: its arguments."""
    iset = osub.add_parser("import-set", help="import the real-object set from pybullet_data (cached)",
                           parents=[parent(workers_option(2), quiet_option)])
    iset.add_argument("--split", choices=("test", "train"), default="test",
                      help="test: 40 of pybullet's test objects + duck, mug, teddy (default); train: 900")
    iset.set_defaults(func=_cmd_objects_import_set)


def _cmd_objects_import_set(args) -> int:
    from kgn_bench.objects.pybullet_set import import_set, set_items
    from kgn_bench.shapes.library import user_root
    from kgn_bench.shapes.mesh_object import MANIFEST

    items = set_items(args.split)
    before = sum((user_root() / it.name / MANIFEST).is_file() for it in items)  # what import_set skips
    started = time.perf_counter()
    failed = import_set(args.split, workers=args.workers, progress=not args.quiet)
    for name, error in failed.items():
        warn(f"{name} refused: {error}")
    done = len(items) - len(failed) - before
    rate = (f", {done} imported now in {time.perf_counter() - started:.0f} s "
            f"({(time.perf_counter() - started) / done:.1f} s an object, {args.workers} worker(s))" if done > 0 else "")
    print(f"pybullet {args.split}: {len(items) - len(failed)} of {len(items)} objects in the library{rate}"
          + (f", {len(failed)} refused" if failed else ""))
    return 0


def _add_check_labeller(osub) -> None:
    """``kgn-bench objects check-labeller``: its arguments."""
    chk = osub.add_parser("check-labeller", help="the mesh labeller against the primitives' closed-form grasps")
    chk.add_argument("--out", type=Path, default=Path("results/labeller"), help="folder for the table and PNGs")
    chk.add_argument("--shapes", nargs="+", help="primitives to check (default all)")
    chk.add_argument("--verify", type=int_at_least(8), default=400, help="labeller candidates checked (400)")
    chk.add_argument("--control", type=int_at_least(0), default=100, help="random control grasps (100)")
    chk.add_argument("--seed", type=int_at_least(0), default=0)
    chk.set_defaults(func=_cmd_objects_check_labeller)


def _cmd_objects_check_labeller(args) -> int:
    import json

    from kgn_bench.io import atomic_write_text, check_writable_dir
    from kgn_bench.objects.labeller_check import check_labeller, format_table, to_json

    check_writable_dir(args.out)
    results = check_labeller(args.shapes, seed=args.seed, verify=args.verify, control=args.control, out=args.out)
    table = format_table(results)
    atomic_write_text(args.out / "agreement.md", table)
    atomic_write_text(args.out / "agreement.json", json.dumps(to_json(results), indent=1) + "\n")
    print(table)
    print(f"wrote {args.out}/agreement.md, agreement.json and one PNG per shape")
    return 0
