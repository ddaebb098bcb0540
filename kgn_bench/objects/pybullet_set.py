"""The real-object set: meshes shipped by the ``pybullet`` package (``pybullet_data``, zlib licence).

``pybullet_data/random_urdfs/NNN/NNN.urdf`` holds 1000 procedural objects; pybullet's own grasping
environment (``KukaDiverseObjectEnv``) splits them 90/10, its test objects being the folders whose number ends
in 0. This set keeps that split:

- ``test``: ``shapes.library.PYBULLET_TEST_COUNT`` (40) of the 100 test objects, drawn without replacement
  with ``numpy.random.default_rng(PYBULLET_SPLIT_SEED)`` and sorted (``shapes.library.pybullet_numbers``),
  named ``pb_NNN``, plus the duck, the mug and the teddy bear of ``pybullet_data`` (``pb_duck``, ``pb_mug``,
  ``pb_teddy``), 43 objects;
- ``train``: the 900 others (``pb_NNN``), importable the same way for training or tuning.

Each is imported with ``objects.importer.import_mesh`` at the scale of its URDF (``random_urdfs`` use 0.015:
6-12 cm), density 700 kg/m³, seeded by its number, into the user's library: a second import of the set skips
what is there. The ``test`` split ships imported with the package (``assets/objects/``, found after the user's
library), so tasks on it run without an import; ``ensure_objects`` imports only what neither holds (the
``train`` split, or a bundled folder that was removed).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from kgn_bench.shapes.library import PYBULLET_EXTRAS, find_object, packaged, pybullet_numbers, user_root
from kgn_bench.shapes.mesh_object import MANIFEST, ObjectError

__all__ = ["LICENCE", "SetItem", "data_path", "ensure_objects", "import_set", "set_items"]

LICENCE = "zlib (pybullet_data, Erwin Coumans and contributors; see the pybullet package's LICENSE.txt)"
_EXTRAS = {"pb_duck": ("duck_vhacd.urdf", 0), "pb_mug": ("objects/mug.urdf", 0), "pb_teddy": ("teddy_vhacd.urdf", 0)}
_EXTRA_SIZE = {"pb_duck": 0.12, "pb_mug": 0.11, "pb_teddy": 0.16}
"""The three named objects are modelled at arbitrary scales; they are scaled to these largest extents (m)."""


@dataclass(frozen=True)
class SetItem:
    """One object of the set: its ``name``, the mesh file, the URDF scale (or a target ``size``) and a seed."""

    name: str
    mesh: Path
    scale: float | None
    size: float | None
    seed: int


def data_path() -> Path:
    """The ``pybullet_data`` folder; ``ObjectError`` if pybullet is not installed."""
    try:
        import pybullet_data
    except ImportError:
        raise ObjectError("the real-object set needs the pybullet package (pip install pybullet)") from None
    return Path(pybullet_data.getDataPath())


def _visual_mesh(urdf: Path) -> tuple[Path, float]:
    """The visual mesh file of a one-link URDF and its (uniform) scale."""
    mesh = ET.parse(urdf).getroot().find("./link/visual/geometry/mesh")
    if mesh is None:
        raise ObjectError(f"{urdf}: no visual mesh")
    scale = float(mesh.get("scale", "1 1 1").split()[0])
    return urdf.parent / mesh.get("filename"), scale


def set_items(split: str = "test") -> list[SetItem]:
    """The objects of ``split`` ("test" or "train"), in a fixed order (module doc)."""
    root = data_path()
    items = []
    for n in pybullet_numbers(split):
        mesh, scale = _visual_mesh(root / "random_urdfs" / f"{n:03d}" / f"{n:03d}.urdf")
        items.append(SetItem(f"pb_{n:03d}", mesh, scale, None, n))
    if split == "test":
        for name, (urdf, seed) in _EXTRAS.items():
            mesh, _ = _visual_mesh(root / urdf)
            items.append(SetItem(name, mesh, None, _EXTRA_SIZE[name], seed))
    return items


def _import_one(item: SetItem) -> tuple[str, str]:
    from kgn_bench.objects.importer import ImportConfig, import_mesh

    config = ImportConfig(scale=item.scale, size=item.size, seed=item.seed, licence=LICENCE,
                          source_note=f"pybullet_data/{item.mesh.relative_to(data_path())}")
    try:
        import_mesh(item.mesh, item.name, config, overwrite=True)
    except ObjectError as e:
        return item.name, str(e)
    return item.name, ""


def _all_items() -> dict[str, SetItem]:
    return {it.name: it for split in ("test", "train") for it in set_items(split)}


def import_set(split: str = "test", workers: int = 1, progress: bool = True,
               names: list[str] | None = None) -> dict[str, str]:
    """Import every object of ``split`` (or the set's objects ``names``) that the user's library lacks, into
    it (a bundled copy does not count: importing is how the bundled test set is re-made); returns
    ``{name: error}`` for the ones that could not be imported (empty when all are in)."""
    from kgn_bench.pool import run_jobs
    from kgn_bench.progress import Progress

    if names is None:
        items = set_items(split)
    else:
        every = _all_items()
        items = [every[n] for n in names]
    todo = [it for it in items if not (user_root() / it.name / MANIFEST).is_file()]
    failed: dict[str, str] = {}
    what = f"import pybullet {split}" if names is None else "import pybullet objects"
    bar = Progress(len(todo), what, unit="objects", enabled=progress)

    def done(result: tuple[str, str]) -> None:
        name, error = result
        if error:
            failed[name] = error
        bar.update(1, f"{len(failed)} refused")

    try:
        run_jobs(todo, _import_one, done, workers=workers, what="object imports")
    finally:
        bar.close()
    return failed


def ensure_objects(names: list[str] | tuple[str, ...], workers: int = 1, progress: bool = True,
                   refusals: bool = False) -> dict[str, str]:
    """Import the packaged objects among ``names`` that the library lacks (the main job calls this, so a
    fresh clone needs no separate import step). ``ObjectError`` names the first that cannot be imported, unless
    ``refusals``: then the ones the importer refuses (a broken mesh: ``pb_168``'s vertices are all NaN) are
    returned as ``{name: reason}`` and the others imported (a set drawn by name, ``pybullet_train:300``, goes
    on without them). An unknown name is an error either way."""
    missing = [n for n in dict.fromkeys(names) if packaged(n) and find_object(n) is None]
    if not missing:
        return {}
    every = _all_items()
    unknown = [n for n in missing if n not in every and n not in PYBULLET_EXTRAS]
    if unknown:
        raise ObjectError(f"unknown object {unknown[0]!r}: not in the pybullet set")
    failed = import_set(workers=workers, progress=progress, names=missing)
    if failed and not refusals:
        name, error = next(iter(failed.items()))
        raise ObjectError(f"object {name!r} of the pybullet set could not be imported: {error}")
    return failed
