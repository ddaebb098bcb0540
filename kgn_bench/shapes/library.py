"""Where imported objects live, and how a task's object name finds its folder.

An object is a folder ``<root>/<name>/`` (``shapes.mesh_object``). The roots are searched in order:

1. the user's library: ``$KGN_BENCH_OBJECTS`` if set, else ``~/.local/share/kgn-bench/objects``
   (``kgn-bench objects add`` and ``kgn-bench objects import-set`` write here);
2. the objects bundled with the package (``assets/objects/``, installed as ``kgn_bench.assets``): the
   real-object test set ``pybullet_test``, imported.

A task names an object by its folder name, exactly as it names a primitive (``[objects] set = ["mug_scan"]``),
or a whole packaged set by the set's name (``[objects] set = "pybullet_test"``, ``OBJECT_SETS``), or the first
``N`` objects of a set in its fixed order as ``"<set>:N"`` (``pybullet_train:300``: a reproducible part of the
900 training objects, for a machine that cannot import them all); the names of primitives and household
objects cannot be reused.

The real-object set's split is defined here, so that a task can name it before it is imported:
``pybullet_data/random_urdfs`` has 1000 objects and pybullet's own grasping environment tests on the 100 whose
number ends in 0; ``pybullet_test`` is ``PYBULLET_TEST_COUNT`` of those, drawn with
``default_rng(PYBULLET_SPLIT_SEED)`` and sorted, plus the duck, mug and teddy (``objects.pybullet_set`` imports
them).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from functools import lru_cache
from pathlib import Path

import numpy as np

from kgn_bench.resources import _package_dir
from kgn_bench.shapes.mesh_object import MANIFEST, MeshObject, ObjectError

__all__ = [
    "ENV_VAR",
    "NAME_PATTERN",
    "OBJECT_SETS",
    "PYBULLET_EXTRAS",
    "PYBULLET_SPLIT_SEED",
    "PYBULLET_TEST_COUNT",
    "find_object",
    "is_set_name",
    "library_roots",
    "list_objects",
    "load_object",
    "object_sha256",
    "packaged",
    "pybullet_numbers",
    "set_names",
    "shadowed",
    "test_set_leaks",
    "user_root",
]

ENV_VAR = "KGN_BENCH_OBJECTS"
NAME_PATTERN = re.compile(r"[a-z0-9][a-z0-9_\-]{0,62}")
"""Object names: lower-case letters, digits, '_' and '-', at most 63 characters (they become folder names)."""


def user_root() -> Path:
    """The user's object library (created on first import)."""
    env = os.environ.get(ENV_VAR)
    return Path(env).expanduser() if env else Path.home() / ".local" / "share" / "kgn-bench" / "objects"


def library_roots() -> list[Path]:
    """The object roots in search order: the user's library, then the bundled objects."""
    return [user_root(), _package_dir("kgn_bench.assets") / "objects"]


def list_objects() -> dict[str, Path]:
    """Every object folder by name (the first root that holds a name wins)."""
    found: dict[str, Path] = {}
    for root in library_roots():
        if root.is_dir():
            for manifest in sorted(root.glob(f"*/{MANIFEST}")):
                if NAME_PATTERN.fullmatch(manifest.parent.name):  # not temporary folders of an import
                    found.setdefault(manifest.parent.name, manifest.parent)
    return found


def find_object(name: str) -> Path | None:
    """The folder of object ``name``, or None."""
    for root in library_roots():
        folder = root / name
        if (folder / MANIFEST).is_file():
            return folder
    return None


@lru_cache(maxsize=256)
def _load(folder: Path, stamp: float) -> MeshObject:
    return MeshObject(folder)


def load_object(name: str) -> MeshObject:
    """The imported object ``name`` (cached per process while its manifest is unchanged)."""
    folder = find_object(name)
    if folder is None:
        raise ObjectError(f"unknown object {name!r}: no folder {name}/ in {', '.join(map(str, library_roots()))}")
    return _load(folder, (folder / MANIFEST).stat().st_mtime)


@lru_cache(maxsize=1024)
def _folder_sha256(folder: Path, stamps: tuple[tuple[str, int, int], ...], made_only: bool = False) -> str:
    """SHA-256 of the files ``stamps`` names in ``folder`` (by relative path); ``made_only`` leaves the
    manifest's stage times out: what an import makes, not how long it took."""
    h = hashlib.sha256()
    for rel, _, _ in stamps:
        data = (folder / rel).read_bytes()
        if made_only and rel == MANIFEST:
            manifest = json.loads(data)
            manifest.pop("timing_s", None)
            data = json.dumps(manifest, sort_keys=True).encode()
        h.update(rel.encode() + b"\0")
        h.update(hashlib.sha256(data).digest())
    return h.hexdigest()


def _stamps(folder: Path) -> tuple[tuple[str, int, int], ...]:
    files = sorted(p for p in folder.rglob("*") if p.is_file() and p.name != "preview.png")
    return tuple((p.relative_to(folder).as_posix(), p.stat().st_mtime_ns, p.stat().st_size) for p in files)


def shadowed(names: list[str] | tuple[str, ...]) -> dict[str, Path]:
    """The objects among ``names`` that the user's library holds with other content than the bundled copy of
    the same name (the stage times of the manifest aside), by the folder tasks get (the user's, searched
    first): a re-import by an older version, or an object added with ``--overwrite``. Runs on them are other
    experiments than the shipped figures."""
    bundled = library_roots()[-1]
    out: dict[str, Path] = {}
    for name in dict.fromkeys(names):
        mine, theirs = user_root() / name, bundled / name
        if (mine / MANIFEST).is_file() and (theirs / MANIFEST).is_file():
            if _folder_sha256(mine, _stamps(mine), True) != _folder_sha256(theirs, _stamps(theirs), True):
                out[name] = mine
    return out


def object_sha256(name: str) -> str | None:
    """SHA-256 of an imported object's content: every file of its folder (manifest, grasps, collision hulls,
    visual mesh; not the preview picture), by relative path; None for a built-in shape. Two runs that name
    the same object with other content are different experiments (``bench.runner.run_identity``)."""
    folder = find_object(name)
    return None if folder is None else _folder_sha256(folder, _stamps(folder))


PYBULLET_SPLIT_SEED = 0
PYBULLET_TEST_COUNT = 40
PYBULLET_EXTRAS = ("pb_duck", "pb_mug", "pb_teddy")
OBJECT_SETS = ("pybullet_test", "pybullet_train")


def pybullet_numbers(split: str) -> list[int]:
    """The ``random_urdfs`` numbers of a split of the real-object set ("test" or "train"; module doc)."""
    if split == "test":
        pool = [n for n in range(1000) if n % 10 == 0]
        return sorted(np.random.default_rng(PYBULLET_SPLIT_SEED).choice(pool, PYBULLET_TEST_COUNT, replace=False)
                      .tolist())
    if split == "train":
        return [n for n in range(1000) if n % 10 != 0]
    raise ObjectError(f"unknown split {split!r} of the pybullet set (test, train)")


def is_set_name(item: str) -> bool:
    """Whether ``item`` names a packaged set or its first objects (``pybullet_train``, ``pybullet_train:300``)."""
    return item.split(":", 1)[0] in OBJECT_SETS


def set_names(set_name: str) -> list[str]:
    """The object names of a packaged set (``OBJECT_SETS``), imported or not, in the set's fixed order; for
    ``"<set>:N"`` the first ``N`` of them (``ObjectError`` if N is not a whole number from 1 to the set's size)."""
    base, sep, count = set_name.partition(":")
    if base not in OBJECT_SETS:
        raise ObjectError(f"unknown object set {base!r} (known: {', '.join(OBJECT_SETS)})")
    split = base.removeprefix("pybullet_")
    names = [f"pb_{n:03d}" for n in pybullet_numbers(split)]
    names = names + list(PYBULLET_EXTRAS) if split == "test" else names
    if not sep:
        return names
    if not count.isdigit() or not 1 <= int(count) <= len(names):
        raise ObjectError(f"{set_name!r}: after ':' give how many of the set's {len(names)} objects to take")
    return names[: int(count)]


def test_set_leaks(names: list[str] | tuple[str, ...]) -> list[str]:
    """The objects among ``names`` that are the real-object test set (``pybullet_test``), by name or, for an
    imported object, by the SHA-256 of the mesh file it was imported from (the manifest's ``source_sha256``
    against the bundled test objects'): training data must hold none. Built-in shapes never leak."""
    test = set(set_names("pybullet_test"))
    hashes = set()
    for name in test:
        folder = find_object(name)
        if folder is not None:
            hashes.add(json.loads((folder / MANIFEST).read_text()).get("source_sha256"))
    leaks = []
    for name in dict.fromkeys(names):
        folder = None if name in test else find_object(name)
        source = json.loads((folder / MANIFEST).read_text()).get("source_sha256") if folder is not None else None
        if name in test or (source is not None and source in hashes):
            leaks.append(name)
    return leaks


def packaged(name: str) -> bool:
    """Whether ``name`` belongs to a packaged set (so that it can be imported on demand)."""
    if name in PYBULLET_EXTRAS:
        return True
    m = re.fullmatch(r"pb_(\d{3})", name)
    return m is not None
