"""VGN's training data on disk, for full-volume supervision: one file per scene, one manifest.

Layout of a dataset folder::

    DIR/scenes/<id>.npz        one scene (below), compressed; written atomically (temporary file, rename)
    DIR/vgn_dataset.json       manifest, written last by ``finalize_dataset``

A scene file holds the network input and every labelled grasp of that scene:

- ``tsdf`` (R, R, R) float32: ``TSDFVolume.network_input()`` of the scene's one noisy side view (GIGA's "dex"
  noise applied to the depth image by the generator before fusion), indexed ``[i, j, k]`` = world x, y, z;
- ``voxels`` (N, 3) float32: each grasp's position in voxel units, VGN's convention: ``p_grid / voxel`` where
  ``p_grid = p_world − giga.WORKSPACE_ORIGIN`` is the grasp's reference point (VGN's TCP,
  ``giga.GRASP_REFERENCE_DEPTH`` behind the grasp frame's origin, the fingertip midpoint, along the approach) in
  the grid frame (world axes, origin at the cube's corner). Voxel ``(i, j, k)`` therefore stands for the point
  ``(i, j, k) · voxel`` (no +½: the TSDF samples voxel centres, the grasp labels do not; the network learns that
  offset and ``detectors.vgn`` decodes with it). The loss reads the network at ``round(voxels)``;
- ``quats`` (N, 4) float32: unit quaternion (w, x, y, z) of ``R_grid_grasp`` (= ``R_world_grasp``: the grid has
  the world's axes), this project's grasp frame (+x approach, z the closing axis; ``kgn_bench.grasp``);
  ``q`` and ``q · R_x(π)`` are the same grasp and either may be stored;
- ``widths`` (N,) float32: the opening in voxels (metres / voxel; VGN stores the measured width of a success
  and the maximum opening of a failure);
- ``labels`` (N,) uint8: 1 = the grasp held, 0 = it failed;
- ``holds`` (N, Y) uint8, optional (label rule v4 on): every tried turn's outcome. ``holds[n, j] = 1`` when the
  grasp ``n`` turned by ``j · π / Y`` about its own approach axis (+x), i.e. ``R_grid_grasp · R_x(j π / Y)``,
  held; ``j = 0`` is the stored rotation itself, so a positive has ``holds[n, 0] = 1`` and a negative no 1 at
  all. The turns and their 180° twins are every rotation about the approach that was tried, so ``holds`` is the
  grasp's whole set of holding closing lines, of which ``quats`` stores one (VGN's label: the middle of the
  widest run);
- ``meta``: a JSON string (the generator's per-scene facts: seed, objects, arrangement), may be ``{}``.

The manifest (``vgn_dataset.json``): ``format`` ("kgn-bench-vgn-dataset"), ``version``, ``grid`` (``size`` m,
``resolution``, ``truncation_voxels``), ``settings`` (the generator's settings, free-form), totals ``scenes``,
``grasps``, ``positives``, ``files`` (per scene: ``id``, ``grasps``, ``positives``, ``sha256`` of the file) and
``sha256``, the SHA-256 of the canonical JSON of ``files``: the dataset's identity (training refuses to resume
on another).

**For the generator**: call ``write_scene(folder, scene_id, tsdf_input, voxels, quats, widths, labels, meta)``
once per scene (any order; a scene written again replaces the old file whole; concurrent writers of different
scenes are safe), then ``finalize_dataset(folder, grid, settings)`` once at the end: it reads every scene file
back, checks it and writes the manifest. Cleaning as VGN does (dropping grasps outside the valid volume,
2 cm from the x/y faces) is the generator's job; balancing positives and negatives is the training's
(``training.vgn_train``), so write every labelled grasp.

Readers: ``read_manifest(folder)`` and ``read_scene(folder, entry_or_id)``; a missing, truncated or altered
file is a ``DatasetError`` whose one line names it.
"""

from __future__ import annotations

import hashlib
import io
import json
import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kgn_bench.data.format import DatasetError
from kgn_bench.io import atomic_write, atomic_write_text
from kgn_bench.tsdf import VoxelGrid

__all__ = [
    "MANIFEST",
    "VGN_DATASET_FORMAT",
    "VGN_DATASET_VERSION",
    "SceneEntry",
    "VGNManifest",
    "VGNScene",
    "finalize_dataset",
    "list_scene_ids",
    "read_manifest",
    "read_scene",
    "scene_path",
    "write_scene",
]

VGN_DATASET_FORMAT = "kgn-bench-vgn-dataset"
VGN_DATASET_VERSION = 1
MANIFEST = "vgn_dataset.json"
_ID = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
_KEYS = ("tsdf", "voxels", "quats", "widths", "labels", "meta")
_OPTIONAL = ("holds",)


def _scene_name(scene_id: int | str) -> str:
    if isinstance(scene_id, (int, np.integer)) and not isinstance(scene_id, bool):
        if scene_id < 0:
            raise ValueError(f"scene id must be ≥ 0, got {scene_id}")
        return f"{int(scene_id):06d}"
    if isinstance(scene_id, str) and _ID.match(scene_id):
        return scene_id
    raise ValueError(f"scene id must be an int ≥ 0 or 1-64 characters of [A-Za-z0-9_-], got {scene_id!r}")


def scene_path(folder: Path, scene_id: int | str) -> Path:
    """The file of scene ``scene_id``: ``folder/scenes/<id>.npz`` (an int id is zero-padded to 6 digits)."""
    return Path(folder) / "scenes" / f"{_scene_name(scene_id)}.npz"


@dataclass(frozen=True)
class VGNScene:
    """One scene as stored (the module docstring gives every array's meaning, frame and unit)."""

    scene_id: str
    tsdf: np.ndarray
    voxels: np.ndarray
    quats: np.ndarray
    widths: np.ndarray
    labels: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)
    holds: np.ndarray | None = None
    """(N, Y) bool, every tried turn's outcome (module docstring), or None in data written without it."""

    def __len__(self) -> int:
        return len(self.labels)


def _check_arrays(tsdf: np.ndarray, voxels: np.ndarray, quats: np.ndarray, widths: np.ndarray,
                  labels: np.ndarray, holds: np.ndarray | None = None) -> str | None:
    """What is wrong with one scene's arrays (None if nothing)."""
    if tsdf.ndim != 3 or len(set(tsdf.shape)) != 1:
        return f"tsdf must be (R, R, R), got {tsdf.shape}"
    if not np.all(np.isfinite(tsdf)):
        return "tsdf has non-finite values"
    n = len(labels)
    if voxels.shape != (n, 3) or quats.shape != (n, 4) or widths.shape != (n,) or labels.shape != (n,):
        return (f"voxels (N, 3), quats (N, 4), widths (N,) and labels (N,) must agree, got {voxels.shape}, "
                f"{quats.shape}, {widths.shape}, {labels.shape}")
    if not (np.all(np.isfinite(voxels)) and np.all(np.isfinite(quats)) and np.all(np.isfinite(widths))):
        return "voxels, quats and widths must be finite"
    if np.any(~np.isin(labels, (0, 1))):
        return "labels must be 0 or 1"
    if n and np.abs(np.linalg.norm(quats, axis=1) - 1.0).max() > 1e-3:
        return "quats must be unit quaternions (w, x, y, z)"
    if np.any(widths < 0):
        return "widths must be ≥ 0"
    r = tsdf.shape[0]
    if n and (voxels.min() < -0.5 or voxels.max() >= r - 0.5):
        return f"voxels must round into the grid [0, {r - 1}]"
    if holds is not None:
        if holds.ndim != 2 or holds.shape[0] != n or holds.shape[1] < 1:
            return f"holds must be (N, Y) with N = {n} labels, got {holds.shape}"
        if np.any(~np.isin(holds, (0, 1))):
            return "holds must be 0 or 1"
        if n and (np.any(holds[:, 0] != labels) or np.any(holds[labels == 0].any(axis=1))):
            return "holds must have its column 0 equal to the labels and no 1 on a negative"
    return None


def write_scene(folder: Path, scene_id: int | str, tsdf_input: np.ndarray, voxels: np.ndarray, quats: np.ndarray,
                widths: np.ndarray, labels: np.ndarray, meta: dict[str, Any] | None = None,
                holds: np.ndarray | None = None) -> Path:
    """Write one scene to ``folder/scenes/<id>.npz`` atomically (a reader, or a rerun after a kill, sees the old
    file or the whole new one); returns its path. Arrays as in the module docstring (any float / int / bool
    dtype: stored as float32 / uint8; ``holds`` only when given). ``ValueError`` naming the problem for arrays
    that do not fit together (a bug in the caller); ``OutputError`` if the folder cannot be written."""
    tsdf = np.asarray(tsdf_input, dtype=np.float32)
    vox = np.asarray(voxels, dtype=np.float32)
    q = np.asarray(quats, dtype=np.float32)
    if vox.size == 0 and q.size == 0:  # a scene without grasps
        vox, q = vox.reshape(0, 3), q.reshape(0, 4)
    w = np.asarray(widths, dtype=np.float32).reshape(-1)
    lab = np.asarray(labels).reshape(-1)
    turns = None if holds is None else np.asarray(holds).astype(np.uint8)
    problem = _check_arrays(tsdf, vox, q, w, lab, turns)
    if problem:
        raise ValueError(f"scene {scene_id!r}: {problem}")
    path = scene_path(folder, scene_id)
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays = {"tsdf": tsdf, "voxels": vox, "quats": q, "widths": w, "labels": lab.astype(np.uint8),
              "meta": np.array(json.dumps(meta or {}, sort_keys=True))}
    if turns is not None:
        arrays["holds"] = turns
    atomic_write(path, lambda f: np.savez_compressed(f, **arrays))
    return path


def _load(path: Path, name: str) -> VGNScene:
    """The scene stored in ``path``; ``DatasetError`` naming the file if it is unreadable or malformed."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise DatasetError(f"{path}: no such scene file") from None
    except OSError as e:
        raise DatasetError(f"{path}: cannot read the scene file ({e.strerror})") from None
    return _parse(raw, path, name)


def _parse(raw: bytes, path: Path, name: str) -> VGNScene:
    try:
        with np.load(io.BytesIO(raw), allow_pickle=False) as z:
            missing = [k for k in _KEYS if k not in z.files]
            if missing:
                raise DatasetError(f"{path}: not a VGN scene file (lacks {', '.join(missing)})")
            arrays = {k: z[k] for k in _KEYS + _OPTIONAL if k in z.files}
        meta = json.loads(str(arrays["meta"]))
    except DatasetError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError, zipfile.LargeZipFile) as e:
        raise DatasetError(f"{path}: damaged scene file ({type(e).__name__})") from None
    holds = arrays.get("holds")
    problem = _check_arrays(arrays["tsdf"], arrays["voxels"], arrays["quats"], arrays["widths"], arrays["labels"],
                            holds)
    if problem:
        raise DatasetError(f"{path}: {problem}")
    return VGNScene(name, arrays["tsdf"], arrays["voxels"], arrays["quats"], arrays["widths"], arrays["labels"],
                    meta if isinstance(meta, dict) else {}, None if holds is None else holds.astype(bool))


@dataclass(frozen=True)
class SceneEntry:
    """One scene of the manifest: ``id`` (file stem), ``grasps``, ``positives`` and the file's ``sha256``."""

    id: str
    grasps: int
    positives: int
    sha256: str

    @property
    def negatives(self) -> int:
        return self.grasps - self.positives


@dataclass(frozen=True)
class VGNManifest:
    """A dataset's manifest (module docstring): its ``folder``, ``grid``, generator ``settings``, ``scenes``
    (sorted by id) and ``sha256`` (the dataset's identity)."""

    folder: Path
    grid: VoxelGrid
    settings: dict[str, Any]
    scenes: tuple[SceneEntry, ...]
    sha256: str
    generation_seconds: float | None = None
    """The scenes' generation times summed (``meta["seconds"]``: arranging, viewing and labelling; CPU-core
    seconds, whatever ran in parallel); None when the generator did not record them."""

    def prefix_sha256(self, n: int = 0) -> str:
        """The identity of the first ``n`` scenes (0: all of them, the manifest's ``sha256``): the SHA-256 of
        their file list, so a training run on a prefix still recognises it after the dataset has grown."""
        if not n or n >= len(self.scenes):
            return self.sha256
        return _files_sha256([{"id": e.id, "grasps": e.grasps, "positives": e.positives, "sha256": e.sha256}
                              for e in self.scenes[:n]])

    @property
    def grasps(self) -> int:
        return sum(s.grasps for s in self.scenes)

    @property
    def positives(self) -> int:
        return sum(s.positives for s in self.scenes)


def _files_sha256(files: list[dict[str, Any]]) -> str:
    return hashlib.sha256(json.dumps(files, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def list_scene_ids(folder: Path) -> list[str]:
    """The ids of the complete scene files in ``folder/scenes``, sorted (temporary files are not listed)."""
    return sorted(p.stem for p in (Path(folder) / "scenes").glob("*.npz") if _ID.match(p.stem))


def finalize_dataset(folder: Path, grid: VoxelGrid | None = None, settings: dict[str, Any] | None = None
                     ) -> VGNManifest:
    """Read back every scene file of ``folder``, check it against ``grid`` (default GIGA's 30 cm, 40³,
    τ = 4 voxels) and write the manifest atomically; returns it. ``DatasetError`` naming the first bad file,
    or if there is no scene."""
    folder = Path(folder)
    grid = grid or VoxelGrid()
    ids = list_scene_ids(folder)
    if not ids:
        raise DatasetError(f"{folder}: no scene files under scenes/")
    files, seconds = [], 0.0
    for name in ids:
        path = folder / "scenes" / f"{name}.npz"
        raw = path.read_bytes()
        scene = _parse(raw, path, name)
        if scene.tsdf.shape != (grid.resolution,) * 3:
            raise DatasetError(f"{path}: a {scene.tsdf.shape} grid, the dataset's is {grid.resolution}³")
        files.append({"id": name, "grasps": len(scene), "positives": int(scene.labels.sum()),
                      "sha256": hashlib.sha256(raw).hexdigest()})
        seconds += sum(float(v) for v in (scene.meta.get("seconds") or {}).values())
    manifest = {
        "format": VGN_DATASET_FORMAT,
        "version": VGN_DATASET_VERSION,
        "grid": {"size": grid.size, "resolution": grid.resolution, "truncation_voxels": grid.truncation_voxels},
        "settings": settings or {},
        "scenes": len(files),
        "grasps": sum(f["grasps"] for f in files),
        "positives": sum(f["positives"] for f in files),
        "files": files,
        "sha256": _files_sha256(files),
        "generation_seconds": round(seconds, 1),
    }
    atomic_write_text(folder / MANIFEST, json.dumps(manifest, indent=1) + "\n")
    return read_manifest(folder)


def read_manifest(folder: Path) -> VGNManifest:
    """The manifest of ``folder``; ``DatasetError`` (one line naming the file) if it is missing, not JSON, of
    another format or version, or altered (its ``sha256`` does not match its file list)."""
    path = Path(folder) / MANIFEST
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise DatasetError(f"{folder}: no VGN dataset here (no {MANIFEST}; the generator's finalize_dataset "
                           "writes it)") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise DatasetError(f"{path}: unreadable manifest ({type(e).__name__})") from None
    if not isinstance(data, dict) or data.get("format") != VGN_DATASET_FORMAT:
        raise DatasetError(f"{path}: not a VGN dataset manifest")
    if data.get("version") != VGN_DATASET_VERSION:
        raise DatasetError(f"{path}: dataset version {data.get('version')}, expected {VGN_DATASET_VERSION}")
    try:
        files = data["files"]
        g = data["grid"]
        grid = VoxelGrid(float(g["size"]), int(g["resolution"]), float(g["truncation_voxels"]))
        scenes = tuple(SceneEntry(str(f["id"]), int(f["grasps"]), int(f["positives"]), str(f["sha256"]))
                       for f in files)
    except (KeyError, TypeError, ValueError) as e:
        raise DatasetError(f"{path}: malformed manifest ({type(e).__name__}: {e})") from None
    if _files_sha256(files) != data.get("sha256"):
        raise DatasetError(f"{path}: the file list does not match the manifest's sha256 (edited by hand?)")
    generation = data.get("generation_seconds")
    return VGNManifest(Path(folder), grid, dict(data.get("settings") or {}), scenes, str(data["sha256"]),
                       float(generation) if isinstance(generation, (int, float)) else None)


def read_scene(folder: Path, scene: SceneEntry | int | str) -> VGNScene:
    """One scene. Given a manifest ``SceneEntry`` the file must also match its SHA-256 and counts; given an id
    it is only parsed. ``DatasetError`` (one line naming the file) if it is missing, damaged or altered."""
    if isinstance(scene, SceneEntry):
        path = Path(folder) / "scenes" / f"{scene.id}.npz"
        try:
            raw = path.read_bytes()
        except FileNotFoundError:
            raise DatasetError(f"{path}: scene file listed in the manifest is missing") from None
        except OSError as e:
            raise DatasetError(f"{path}: cannot read the scene file ({e.strerror})") from None
        if hashlib.sha256(raw).hexdigest() != scene.sha256:
            raise DatasetError(f"{path}: SHA-256 differs from the manifest (damaged or replaced file)")
        loaded = _parse(raw, path, scene.id)
        if len(loaded) != scene.grasps or int(loaded.labels.sum()) != scene.positives:
            raise DatasetError(f"{path}: grasp counts differ from the manifest")
        return loaded
    name = _scene_name(scene)
    return _load(Path(folder) / "scenes" / f"{name}.npz", name)
