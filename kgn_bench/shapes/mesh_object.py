"""Objects imported from a mesh: an object folder on disk, read back as a ``Shape``.

An object folder (written by ``kgn_bench.objects.importer``) holds:

- ``object.json``: the manifest (name, source file and its SHA-256, scale, mass, colour, the rest poses, how
  the collision shape and the grasps were made, the licence of the source, and the SHA-256 of every content
  file, ``files_sha256``, which ``check_object`` verifies);
- ``visual.ply``: the visual mesh in the object frame, as imported (scaled, repaired, not simplified);
- ``collision/hull_KK.ply``: the convex pieces of the collision shape (CoACD);
- ``grasps.npz``: the physics-verified grasps in the object frame (``poses`` (N, 4, 4), ``widths`` (N,));
- ``preview.png``: the object with its grasps.

Object frame: the origin at the visual mesh's centre of mass, axes those of the source file (scaled to metres).
The grasps are the family of this object: the oracle, the collision labelling and the vision ground truth use
them exactly as they use the primitives' closed-form families (``Shape.grasps``).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import trimesh

from kgn_bench.errors import KGNBenchError
from kgn_bench.grasp import GraspSet
from kgn_bench.shapes.base import GeomSpec, GraspDensity, RestPose, Shape

__all__ = ["CONTENT_FILES", "MANIFEST", "MANIFEST_VERSION", "MeshObject", "ObjectError", "check_object",
           "content_hashes"]

MANIFEST = "object.json"
MANIFEST_VERSION = 1


class ObjectError(KGNBenchError, ValueError):
    """An object folder or a mesh that cannot be used (the message names the file and the reason)."""


def _read_manifest(folder: Path) -> dict:
    path = folder / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        raise ObjectError(f"{folder}: not an object folder (no {MANIFEST})") from None
    except (OSError, json.JSONDecodeError) as e:
        raise ObjectError(f"{path}: unreadable manifest ({e})") from None
    if not isinstance(manifest, dict) or manifest.get("version") != MANIFEST_VERSION:
        raise ObjectError(f"{path}: manifest version {manifest.get('version')!r}, expected {MANIFEST_VERSION}")
    return manifest


def _load_ply(path: Path) -> trimesh.Trimesh:
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # trimesh raises many types on a corrupt file
        raise ObjectError(f"{path}: unreadable mesh ({e})") from None
    if len(mesh.faces) == 0 or not np.all(np.isfinite(mesh.vertices)):
        raise ObjectError(f"{path}: empty or non-finite mesh")
    return mesh


CONTENT_FILES = ("visual.ply", "grasps.npz", "collision/hull_*.ply")
"""The files whose SHA-256 the manifest records (``files_sha256``) and ``check_object`` verifies."""


def content_hashes(folder: Path) -> dict[str, str]:
    """SHA-256 of each content file of an object folder (``CONTENT_FILES``), by relative path."""
    files = sorted(p for pattern in CONTENT_FILES for p in Path(folder).glob(pattern))
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def check_object(folder: Path) -> None:
    """Verify an object folder before it is used: a readable manifest, as many collision hulls as it records,
    every file with the SHA-256 it records (objects imported before hashes were recorded skip that), and
    readable grasps. ``ObjectError`` names the object and the file: a damaged library is an error, not a
    trial outcome."""
    folder = Path(folder)
    manifest = _read_manifest(folder)
    hulls = sorted((folder / "collision").glob("hull_*.ply"))
    if len(hulls) != manifest.get("hulls", len(hulls)):
        raise ObjectError(f"{folder}: collision/ holds {len(hulls)} hulls, its manifest records {manifest['hulls']} "
                          "(a damaged object folder: import it again)")
    recorded = manifest.get("files_sha256")
    if recorded is not None:
        found = content_hashes(folder)
        for rel in sorted(set(recorded) | set(found)):
            if rel not in found:
                raise ObjectError(f"{folder / rel}: missing (a damaged object folder: import it again)")
            if found[rel] != recorded.get(rel):
                raise ObjectError(f"{folder / rel}: its SHA-256 differs from the manifest's (a damaged or edited "
                                  "object folder: import it again)")
    MeshObject(folder).verified_grasps  # noqa: B018  (reads grasps.npz: a truncated file fails here)


@dataclass(frozen=True, eq=False)
class MeshObject(Shape):
    """An imported object: its folder ``folder`` (see the module doc). The manifest's ``name`` is the name
    tasks use (``[objects] set = ["mug_scan"]``). One folder is one object: ``sample`` returns it as it is
    (its size is fixed at import)."""

    folder: Path
    axisymmetric = False
    grasps_verified = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "folder", Path(self.folder))
        _read_manifest(self.folder)

    @cached_property
    def manifest(self) -> dict:
        return _read_manifest(self.folder)

    @property
    def object_name(self) -> str:
        return str(self.manifest["name"])

    # Shape's class-level ``name`` is per class; an imported object names itself per instance.
    @property
    def name(self) -> str:  # type: ignore[override]
        return self.object_name

    @property
    def density(self) -> float:  # type: ignore[override]
        return float(self.manifest["density"])

    MASS_RANGE = (0.01, 2.0)

    @classmethod
    def sample(cls, rng: np.random.Generator) -> Shape:
        raise TypeError("a MeshObject is loaded from its folder (shapes.library.load_object), not sampled")

    @classmethod
    def from_dims(cls, dims: dict) -> Shape:
        # The library (shapes.library) finds folders by name and sits above this module, so a name is
        # resolved there, never here: this module imports nothing of the library.
        raise TypeError("a MeshObject is loaded from its folder by name (shapes.shape_from_dims or "
                        "shapes.library.load_object), not built from dims")

    def dims(self) -> dict:
        return {"object": self.object_name}

    def _build_mesh(self) -> trimesh.Trimesh:
        return _load_ply(self.folder / "visual.ply")

    @cached_property
    def hulls(self) -> list[trimesh.Trimesh]:
        """The convex pieces of the collision shape, in the object frame."""
        paths = sorted((self.folder / "collision").glob("hull_*.ply"))
        if not paths:
            raise ObjectError(f"{self.folder}: no collision hulls in collision/")
        if len(paths) != self.manifest.get("hulls", len(paths)):
            raise ObjectError(f"{self.folder}: collision/ holds {len(paths)} hulls, its manifest records "
                              f"{self.manifest['hulls']} (a damaged object folder: import it again)")
        return [_load_ply(p) for p in paths]

    def collision_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("mesh", mesh=h) for h in self.hulls]

    def visual_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("mesh", mesh=self.mesh())]

    def rest_poses(self) -> list[RestPose]:
        poses = self.manifest["rest_poses"]
        return [RestPose(np.asarray(p["R"], dtype=float), float(p["probability"])) for p in poses]

    def volume(self) -> float:
        return float(self.manifest["volume"])

    def mass(self) -> float:
        return float(self.manifest["mass"])

    def contains(self, points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        inside = np.zeros(len(points), dtype=bool)
        for h in self.hulls:
            inside |= GeomSpec("mesh", mesh=h).contains(points)
        return inside

    @cached_property
    def verified_grasps(self) -> GraspSet:
        """Every grasp that held in the physics check, in the object frame (``grasps.npz``)."""
        path = self.folder / "grasps.npz"
        try:
            with np.load(path) as z:
                poses, widths = np.asarray(z["poses"], dtype=float), np.asarray(z["widths"], dtype=float)
        except Exception as e:  # OSError, KeyError, ValueError, zipfile.BadZipFile, EOFError: a damaged file
            raise ObjectError(f"{path}: unreadable grasps ({type(e).__name__}: {e})") from None
        return GraspSet.unlabelled(poses, widths)

    def grasps(self, density: GraspDensity) -> GraspSet:
        """The verified grasps. ``density`` sets how many: at most ``translations × angles × 4`` of them, an
        even (deterministic) subsample when there are more, so the training density stays sparser than the
        evaluation one as for the closed-form families."""
        allg = self.verified_grasps
        limit = density.translations * density.angles * 4
        if len(allg) <= limit:
            return allg
        keep = np.linspace(0, len(allg) - 1, limit).round().astype(int)
        return GraspSet.unlabelled(allg.poses[keep], allg.widths[keep])
