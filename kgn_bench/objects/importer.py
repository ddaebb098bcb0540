"""``kgn-bench objects add``: turn a user's mesh into an object folder (``shapes.mesh_object``).

The steps, each of which refuses a bad mesh with one ``ObjectError`` line and writes nothing:

1. **read** OBJ, STL, PLY, GLB/GLTF (or anything else trimesh reads) as one mesh; a scene is concatenated;
2. **repair**: merge seam vertices, drop degenerate and duplicate faces, fix winding and normals, fill small
   holes, cap larger open loops, unite overlapping parts; the result must be a watertight, finite, non-empty
   solid (the antipodal rays need an inside). A surface that stays open or non-manifold is rebuilt by the
   fallback (``objects.remesh.voxel_remesh`` at ``REMESH_PITCH`` in the object's final size, open sheets
   thickened into walls), and the manifest's ``remeshed`` entry records why, the pitch and the largest
   deviation from the file's surface, which ``kgn-bench objects add`` prints as a warning;
3. **scale** by ``scale`` or to ``size`` (the largest extent, m); the object frame's origin is moved to the
   centre of mass, the axes are kept;
4. **check the size**: the largest extent at most ``MAX_EXTENT`` (what the table's workspace holds), the
   smallest at least ``MIN_EXTENT``;
5. **decompose** the collision shape with CoACD (``hulls`` at most, seeded), cached by the SHA-256 of the
   repaired mesh and the settings, so a re-import costs nothing;
6. **rest poses** from trimesh's quasi-static estimate (``compute_stable_poses``), the likely ones kept;
7. **grasps**: antipodal candidates (``shapes.grasp_sampling``), and for each rest pose in which fewer than
   ``objects.coverage.REST_GRASPS`` of them are executable, more aimed from above it (``_aim_at_short_poses``;
   the manifest's ``grasps.aimed`` counts them); at most ``verify`` checked in physics (``sim.grasp_verify``):
   first ``objects.coverage.REST_GRASPS`` spread ones that the gripper can execute in
   each rest pose (from above the table, ``objects.coverage``), then spread over closing and approach
   directions (``shapes.grasp_sampling.diverse_subset``); a rest pose left with fewer than a third of that
   holding gets as many candidates more, once. The ones that hold are the object's grasps (at least
   ``MIN_GRASPS``), and each rest pose in the manifest says how many of them it can execute (``grasps``);
8. **write** the folder atomically (a temporary folder renamed into place) with a preview PNG.

Mass: ``mass`` if given, else ``density`` (kg/m³, default 700 as in VGN/GIGA) × volume.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import tempfile
import time
import zipfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from kgn_bench.gripper import GRIPPER
from kgn_bench.objects.coverage import REST_GRASPS, coverage_subset, executable
from kgn_bench.objects.remesh import REMESH_PITCH, voxel_remesh
from kgn_bench.shapes import OBJECTS
from kgn_bench.shapes.grasp_sampling import SamplingConfig, sample_antipodal_grasps
from kgn_bench.shapes.library import NAME_PATTERN, OBJECT_SETS, packaged, user_root
from kgn_bench.shapes.mesh_object import MANIFEST, MANIFEST_VERSION, MeshObject, ObjectError, content_hashes

__all__ = ["MAX_EXTENT", "MIN_EXTENT", "MIN_GRASPS", "ImportConfig", "UnclosedSurfaceError", "import_mesh",
           "repair_mesh"]

MAX_EXTENT = 0.30
"""Largest object extent (m): the pile box and the packed square are 30 cm, the gripper opens 20 cm."""
MIN_EXTENT = 0.005
MIN_GRASPS = 8
"""An object needs at least this many verified grasps (the oracle and the labels draw from them)."""
MAX_FACES = 200_000


@dataclass(frozen=True)
class ImportConfig:
    """Settings of one import (every field is recorded in the manifest)."""

    scale: float | None = None
    size: float | None = None
    density: float = 700.0
    mass: float | None = None
    color: tuple[float, float, float] = (0.7, 0.55, 0.35)
    hulls: int = 8
    coacd_threshold: float = 0.05
    seed: int = 0
    verify: int = 160
    sampling: SamplingConfig = field(default_factory=SamplingConfig)
    licence: str = "unknown"
    source_note: str = ""

    def __post_init__(self) -> None:
        if self.scale is not None and self.size is not None:
            raise ObjectError("give --scale or --size, not both")
        for key in ("scale", "size", "mass"):
            v = getattr(self, key)
            if v is not None and not (np.isfinite(v) and v > 0):
                raise ObjectError(f"--{key} must be a positive number, got {v}")
        if not (np.isfinite(self.density) and self.density > 0):
            raise ObjectError(f"--density must be positive, got {self.density}")
        if len(self.color) != 3 or not all(0.0 <= c <= 1.0 for c in self.color):
            raise ObjectError(f"--color needs three numbers in [0, 1], got {self.color}")
        if self.hulls < 1 or self.verify < MIN_GRASPS:
            raise ObjectError(f"--hulls must be ≥ 1 and --verify ≥ {MIN_GRASPS}")


MAX_UNPACKED = 256_000_000
"""Largest unpacked size of a 3MF file (a zip) that is read."""
ARCHIVE_MAGIC = (b"PK\x03\x04", b"\x1f\x8b", b"BZh", b"\xfd7zXZ", b"7z\xbc\xaf", b"Rar!")
"""Leading bytes of zip, gzip, bzip2, xz, 7z and rar files: trimesh would unpack them in memory, without a
bound on the size, so an archive is refused before it is read."""


class UnclosedSurfaceError(ObjectError):
    """A surface that repair leaves open or non-manifold (the importer's fallback remeshes it)."""


def _read(path: Path) -> trimesh.Trimesh:
    if not path.is_file():
        raise ObjectError(f"{path}: no such file")
    with open(path, "rb") as f:
        head = f.read(8)
    if path.suffix.lower() == ".3mf":  # a mesh format that is a zip: read, with its unpacked size bounded
        try:
            with zipfile.ZipFile(path) as z:
                unpacked = sum(i.file_size for i in z.infolist())
        except zipfile.BadZipFile:
            raise ObjectError(f"{path}: not a readable 3MF (zip) file") from None
        if unpacked > MAX_UNPACKED:
            raise ObjectError(f"{path}: unpacks to {unpacked / 1e6:.0f} MB, more than {MAX_UNPACKED / 1e6:.0f} MB")
    elif head.startswith(ARCHIVE_MAGIC) or path.suffix.lower() in (".zip", ".gz", ".tgz", ".bz2", ".xz", ".7z",
                                                                     ".tar"):
        raise ObjectError(f"{path}: an archive; unpack it and import the mesh file inside (OBJ, STL, PLY, GLB, ...)")
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # trimesh raises many types on a bad file
        raise ObjectError(f"{path}: unreadable mesh ({type(e).__name__}: {e})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise ObjectError(f"{path}: the file holds no triangles")
    return loaded


def _cap_open_loops(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh`` with every boundary loop closed by a fan of triangles about the loop's centroid (a new vertex).

    A boundary edge is one that a single face uses; followed in that face's direction the boundary edges form
    loops. The cap triangle of edge (a, b) is (b, a, c), wound against the face that owns the edge, so the
    cap's orientation agrees with the surface's. Enough for the holes meshes commonly have (a tube left open
    where it meets a body, a missing lid) and what trimesh's ``fill_holes`` (triangles and quads only) leaves;
    a loop through a vertex twice (a bow-tie) is left open."""
    rows = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
    if len(rows) == 0:
        return mesh
    edges = mesh.edges[rows]
    following: dict[int, int] = {}
    for a, b in edges.tolist():
        if a in following:  # a bow-tie vertex: the loops through it are ambiguous
            return mesh
        following[a] = b
    vertices, faces = [mesh.vertices], [mesh.faces]
    n = len(mesh.vertices)
    seen: set[int] = set()
    for start in following:
        if start in seen:
            continue
        loop, v = [], start
        while v not in seen and v in following:
            seen.add(v)
            loop.append(v)
            v = following[v]
        if v != start or len(loop) < 3:
            continue
        vertices.append(mesh.vertices[loop].mean(axis=0, keepdims=True))
        ring = np.asarray(loop)
        faces.append(np.column_stack([np.roll(ring, -1), ring, np.full(len(ring), n)]))
        n += 1
    return trimesh.Trimesh(np.vstack(vertices), np.vstack(faces), process=True)


def _defects(mesh: trimesh.Trimesh) -> str:
    """The open and the non-manifold edges (used by more than two faces) of ``mesh``, in words."""
    _, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    return f"{int((counts == 1).sum())} open edges, {int((counts > 2).sum())} edges shared by more than two faces"


def repair_mesh(mesh: trimesh.Trimesh, origin: str = "mesh") -> trimesh.Trimesh:
    """A watertight copy of ``mesh``: seams merged, degenerate and duplicate faces dropped, winding made
    consistent, small holes filled and larger boundary loops capped (``_cap_open_loops``), the connected parts
    united into one solid (manifold3d, so parts that overlap or touch along an edge stop counting twice), and
    the normals pointing out. ``ObjectError`` (naming ``origin``) when it is empty, not finite, or still not
    closed afterwards (``UnclosedSurfaceError`` when it is open or its parts cannot be united)."""
    if not np.all(np.isfinite(mesh.vertices)):
        raise ObjectError(f"{origin}: non-finite vertex coordinates")
    if len(mesh.faces) > MAX_FACES:
        raise ObjectError(f"{origin}: {len(mesh.faces)} faces, more than {MAX_FACES}; decimate it first")
    m = trimesh.Trimesh(mesh.vertices.copy(), mesh.faces.copy(), process=True)  # merges duplicate vertices
    m.merge_vertices(merge_tex=True, merge_norm=True)
    m.update_faces(m.nondegenerate_faces())
    m.update_faces(m.unique_faces())
    m.remove_unreferenced_vertices()
    if len(m.faces) < 4:
        raise ObjectError(f"{origin}: empty mesh after removing degenerate faces")
    trimesh.repair.fix_winding(m)
    trimesh.repair.fill_holes(m)
    if not m.is_watertight:
        m = _cap_open_loops(m)
    parts = m.split(only_watertight=False)
    if len(parts) > 1 and all(p.is_watertight for p in parts):
        for p in parts:
            trimesh.repair.fix_normals(p)
        try:
            m = trimesh.boolean.union(parts, engine="manifold")
        except Exception as e:  # manifold3d refuses what it cannot read as a solid
            raise UnclosedSurfaceError(f"{origin}: its {len(parts)} parts cannot be united "
                                       f"({type(e).__name__}: {e})") from None
    trimesh.repair.fix_normals(m)
    if not m.is_watertight:
        raise UnclosedSurfaceError(f"{origin}: not a closed surface after repair ({_defects(m)})")
    if m.volume <= 0:
        raise ObjectError(f"{origin}: the repaired surface encloses no volume")
    return m


def _decompose(mesh: trimesh.Trimesh, config: ImportConfig, cache: Path) -> list[trimesh.Trimesh]:
    """CoACD's convex pieces of ``mesh``, cached under ``cache`` by the mesh's and the settings' hash (and
    CoACD's version). CoACD runs in a child process (``objects.coacd_worker``); if it crashes, it runs once
    more with its own manifold preprocessing and the next seed."""
    from importlib.metadata import version

    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    h.update(json.dumps([config.hulls, config.coacd_threshold, config.seed, version("coacd")]).encode())
    path = cache / f"{h.hexdigest()}.npz"
    if path.is_file():
        with np.load(path) as z:
            n = int(z["count"])
            return [trimesh.Trimesh(z[f"v{k}"], z[f"f{k}"], process=False) for k in range(n)]
    from kgn_bench.objects.coacd_worker import CoACDCrash, decompose

    settings = dict(threshold=config.coacd_threshold, max_convex_hull=config.hulls, seed=config.seed,
                    resolution=1000, preprocess_resolution=30, mcts_iterations=60)
    try:
        parts = decompose(mesh.vertices, mesh.faces, settings)
    except CoACDCrash as first:
        # CoACD's own preprocessing (a manifold remesh) and another seed route around the crashes seen so far
        try:
            parts = decompose(mesh.vertices, mesh.faces, {**settings, "seed": config.seed + 1,
                                                          "preprocess_mode": "on"})
        except CoACDCrash as e:
            raise ObjectError(f"convex decomposition failed twice: {first}; then, with CoACD's preprocessing, "
                              f"{e}") from None
    hulls = []
    for v, f in parts:
        hull = _bounded(trimesh.Trimesh(np.asarray(v), np.asarray(f), process=True).convex_hull, MAX_HULL_VERTICES)
        if len(hull.faces) >= 4 and hull.volume > 1e-9:
            hulls.append(hull)
    if not hulls:
        raise ObjectError("CoACD decomposition gave no usable convex piece")
    cache.mkdir(parents=True, exist_ok=True)
    arrays = {"count": np.array(len(hulls))}
    for k, hull in enumerate(hulls):
        arrays[f"v{k}"], arrays[f"f{k}"] = hull.vertices, hull.faces
    tmp = path.with_suffix(".tmp.npz")
    np.savez(tmp, **arrays)
    tmp.replace(path)
    return hulls


REST_HULL_FACES = 2000
"""The rest-pose search works on the convex hull; a hull with more faces than this is rebuilt from
``REST_HULL_VERTICES`` of its vertices (``_bounded``), so the search's cost is bounded
whatever the mesh (a 20 000-face sphere took 66 s before, a 199 000-face one 4.6 GB)."""
REST_HULL_VERTICES = 600


MAX_HULL_VERTICES = 4096
"""Most vertices of one collision hull: MuJoCo's convex collision visits every vertex, so a hull of a finely
tessellated round object (a 82 000-face sphere gives one of 39 450) slows the physics check and every trial;
a larger hull is rebuilt from this many of its vertices (``_bounded``). The shipped objects' hulls have at
most 3 031."""


def _bounded(hull: trimesh.Trimesh, vertices: int) -> trimesh.Trimesh:
    """``hull`` (convex) if it has at most ``vertices`` vertices, else the convex hull of that many of its
    vertices drawn without replacement by a fixed-seed generator (the same subset on every machine; a hull's
    vertices are spread over its surface already, so a uniform draw keeps its shape: a 39 450-vertex sphere
    hull kept 99.7 % of its volume with 4 096)."""
    points = np.asarray(hull.vertices)
    if len(points) <= vertices:
        return hull
    chosen = np.sort(np.random.default_rng(0).choice(len(points), vertices, replace=False))
    return trimesh.Trimesh(points[chosen]).convex_hull


def _bounded_hull(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """The convex hull of ``mesh`` (what resting depends on), with at most about ``REST_HULL_FACES`` faces."""
    hull = mesh.convex_hull
    return hull if len(hull.faces) <= REST_HULL_FACES else _bounded(hull, REST_HULL_VERTICES)


def _rest_poses(mesh: trimesh.Trimesh, seed: int) -> list[dict]:
    """The likely resting orientations (probability ≥ 2 %, at most 8, renormalised) as rotations.

    Rotations and probabilities are rounded to 9 decimals: trimesh's stable-pose probabilities differ in their
    last bits between CPUs (measured: 0.25726290473703906 on one, ...894 on another), and the manifest must be
    the same wherever the object is imported."""
    transforms, probs = trimesh.poses.compute_stable_poses(_bounded_hull(mesh), center_mass=mesh.center_mass,
                                                           n_samples=1, threshold=0.0, sigma=0.0)
    order = np.argsort(-np.asarray(probs))
    keep = [i for i in order if probs[i] >= 0.02][:8] or [int(order[0])]
    total = float(sum(probs[i] for i in keep))
    return [{"R": np.asarray(transforms[i])[:3, :3].round(9).tolist(), "probability": round(float(probs[i]) / total, 9)}
            for i in keep]


def _write_manifest(folder: Path, manifest: dict) -> None:
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")


def _target(name: str, root: Path | None, overwrite: bool) -> tuple[Path, Path]:
    """The library root and the object folder ``root/name``; refuses a bad or taken name (step 0)."""
    if not NAME_PATTERN.fullmatch(name):
        raise ObjectError(f"object name {name!r}: use lower-case letters, digits, '_' and '-' (≤ 63 characters)")
    if name in OBJECTS:
        raise ObjectError(f"object name {name!r} is a built-in object type; choose another")
    if name in OBJECT_SETS:
        raise ObjectError(f"object name {name!r} is an object set's name, which tasks could never reach; choose "
                          "another")
    if packaged(name) and not overwrite:
        raise ObjectError(f"object name {name!r} belongs to a packaged set (pybullet_test/pybullet_train); pass "
                          "--overwrite to shadow it in every task that names it")
    root = Path(root) if root is not None else user_root()
    target = root / name
    if (target / MANIFEST).exists() and not overwrite:
        raise ObjectError(f"object {name!r} already exists in {root} (pass --overwrite to replace it)")
    return root, target


def _scale(config: ImportConfig, mesh: trimesh.Trimesh) -> float:
    """Step 3's factor: ``config.scale``, else ``config.size`` over the mesh's largest extent, else 1."""
    if config.scale is not None:
        return config.scale
    return config.size / float(mesh.extents.max()) if config.size is not None else 1.0


def _repaired(loaded: trimesh.Trimesh, config: ImportConfig, path: Path, say: Callable[[str], None]
              ) -> tuple[trimesh.Trimesh, dict | None]:
    """Step 2: the repaired mesh, or the fallback's remesh of a surface that repair cannot close, with the
    manifest's ``remeshed`` entry (None when repair sufficed). The pitch is ``REMESH_PITCH`` at the scale
    step 3 will apply (``config.scale``, or ``config.size`` over the file's largest extent)."""
    try:
        return repair_mesh(loaded, str(path)), None
    except UnclosedSurfaceError as e:
        reason = str(e).removeprefix(f"{path}: ")
    scale = _scale(config, loaded)
    say(f"remeshing: {reason}")
    r = voxel_remesh(loaded, REMESH_PITCH / scale, origin=str(path), seed=config.seed)
    return r.mesh, {"reason": reason, "pitch_m": round(r.pitch * scale, 6),
                    "deviation_m": round(r.deviation * scale, 6), "thickened": r.thickened > 0}


def _scale_and_centre(mesh: trimesh.Trimesh, config: ImportConfig, path: Path) -> tuple[float, np.ndarray]:
    """Steps 3-4, in place: scale the repaired mesh by ``config.scale`` or to ``config.size``, check its
    extents, and move the origin to its centre of mass (the object frame keeps the file's axes). Returns the
    scale and the extents (m) after scaling."""
    scale = _scale(config, mesh)
    mesh.apply_scale(scale)
    ext = mesh.extents
    if ext.max() > MAX_EXTENT:
        raise ObjectError(f"{path}: {ext.max():.3f} m across after scaling, more than the workspace's "
                          f"{MAX_EXTENT} m (pass --scale or --size)")
    if ext.min() < MIN_EXTENT:
        raise ObjectError(f"{path}: only {ext.min() * 1000:.1f} mm thick after scaling (at least "
                          f"{MIN_EXTENT * 1000:.0f} mm)")
    mesh.apply_translation(-mesh.center_mass)
    return scale, ext


def _candidates(mesh: trimesh.Trimesh, rng: np.random.Generator, config: ImportConfig,
                path: Path) -> tuple[np.ndarray, np.ndarray, float]:
    """Step 7's candidates: every antipodal grasp (object frame) and its width, with the sampling's seconds."""
    t1 = time.perf_counter()
    poses, widths = sample_antipodal_grasps(mesh, rng, config.sampling)
    t_sample = time.perf_counter() - t1
    if len(poses) == 0:
        raise ObjectError(f"{path}: no antipodal grasp the gripper can span (nothing between "
                          f"{config.sampling.min_extent * 1000:.0f} mm and the {GRIPPER.max_width * 100:.0f} cm "
                          "opening with both contacts inside the friction cone)")
    return poses, widths, t_sample


def _manifest(name: str, path: Path, source_bytes: bytes, config: ImportConfig, mesh: trimesh.Trimesh,
              scale: float, ext: np.ndarray, hulls: int) -> dict:
    """The manifest before the grasp check: identity, source, licence, scale, extents, mass, hulls, rest poses
    (step 6) and the import settings."""
    volume = float(mesh.volume)
    mass = config.mass if config.mass is not None else config.density * volume
    return {
        "version": MANIFEST_VERSION, "name": name, "source": path.name,
        "source_sha256": hashlib.sha256(source_bytes).hexdigest(), "licence": config.licence,
        "source_note": config.source_note, "scale": scale, "extents_m": ext.round(6).tolist(),
        "faces": len(mesh.faces), "volume": volume, "mass": float(mass),
        "density": float(mass / volume), "color": list(config.color), "hulls": hulls,
        "rest_poses": _rest_poses(mesh, config.seed),
        "import": {k: v for k, v in asdict(config).items() if k not in ("licence", "source_note")},
    }


def _keep_held(tmp: Path, mesh: trimesh.Trimesh, manifest: dict, poses: np.ndarray, widths: np.ndarray,
               config: ImportConfig, rng: np.random.Generator, path: Path, say: Callable[[str], None]
               ) -> tuple[dict, float]:
    """Step 7's check on the half-written folder ``tmp``: choose candidates among ``poses`` (``widths``) so
    that every rest pose of ``manifest`` gets some it can execute (``objects.coverage``), check them in physics
    (``sim.grasp_verify``), top up a rest pose left short once, and save the ones that hold to ``grasps.npz``;
    each rest pose of ``manifest`` gets its count of them (``grasps``). Returns the manifest's ``grasps``
    entry and the check's seconds."""
    from kgn_bench.sim.grasp_verify import verify_grasps

    np.savez(tmp / "grasps.npz", poses=np.zeros((0, 4, 4)), widths=np.zeros(0))
    shape = MeshObject(tmp)
    rotations = [r["R"] for r in manifest["rest_poses"]]
    ok = executable(mesh, rotations, poses, widths)
    poses, widths, ok, aimed = _aim_at_short_poses(mesh, rotations, poses, widths, ok, config, rng)
    checked, held = np.zeros(len(poses), dtype=bool), np.zeros(len(poses), dtype=bool)
    t1 = time.perf_counter()
    pick = coverage_subset(ok, poses, config.verify, rng)
    for round_ in range(2):
        if len(pick) == 0:
            break
        say(f"checking {len(pick)} grasps in physics" + (" (rest poses left short)" if round_ else ""))
        held[pick] = verify_grasps(shape, poses[pick], widths[pick])
        checked[pick] = True
        short = [k for k in range(len(ok)) if (ok[k] & held).sum() < REST_GRASPS / 3 and (ok[k] & ~checked).any()]
        pick = coverage_subset(ok[short], poses, REST_GRASPS * len(short), rng, exclude=checked) if short else []
    t_verify = time.perf_counter() - t1
    if held.sum() < MIN_GRASPS:
        raise ObjectError(f"{path}: only {int(held.sum())} of {int(checked.sum())} checked grasps held in physics "
                          f"(at least {MIN_GRASPS} needed)")
    np.savez(tmp / "grasps.npz", poses=poses[held], widths=widths[held])
    for rest, row in zip(manifest["rest_poses"], ok):
        rest["grasps"] = int((row & held).sum())
    counts = {"candidates": len(poses), "checked": int(checked.sum()), "held": int(held.sum())}
    return counts | ({"aimed": aimed} if aimed else {}), t_verify


def _aim_at_short_poses(mesh: trimesh.Trimesh, rotations: list, poses: np.ndarray, widths: np.ndarray,
                        ok: np.ndarray, config: ImportConfig, rng: np.random.Generator
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """More candidates for each rest pose in which fewer than ``REST_GRASPS`` of ``poses`` are executable
    (``ok``, (K, N)): antipodal grasps aimed from above it (``sample_antipodal_grasps`` toward ``R⁻¹ (0, 0,
    −1)``, object frame), so that an object resting on a side the uniform sampling rarely approaches from above
    (the Stanford bunny on its flank: 1 of 205) still gets grasps the selector can take. Returns the candidates
    and their ``ok`` with the aimed ones appended, and how many were added (0: the inputs unchanged)."""
    extra_p, extra_w = [], []
    for k, R in enumerate(rotations):
        if ok[k].sum() < REST_GRASPS:
            down = np.asarray(R, dtype=float).T @ np.array([0.0, 0.0, -1.0])
            p, w = sample_antipodal_grasps(mesh, rng, config.sampling, toward=down)
            extra_p.append(p)
            extra_w.append(w)
    added = sum(len(w) for w in extra_w)
    if not added:
        return poses, widths, ok, 0
    extra_p, extra_w = np.concatenate(extra_p), np.concatenate(extra_w)
    ok = np.concatenate([ok, executable(mesh, rotations, extra_p, extra_w)], axis=1)  # per candidate: new ones only
    return np.concatenate([poses, extra_p]), np.concatenate([widths, extra_w]), ok, added


def import_mesh(path: str | Path, name: str, config: ImportConfig = ImportConfig(), root: Path | None = None,
                overwrite: bool = False, preview: bool = True, progress: Callable[[str], None] | None = None) -> Path:
    """Import the mesh file ``path`` as object ``name`` into ``root`` (default the user's library); returns
    the new object folder. The steps are in the module doc; ``progress`` is told each stage as it starts."""
    say = progress or (lambda _: None)
    path = Path(path)
    t0 = time.perf_counter()
    root, target = _target(name, root, overwrite)
    source_bytes = path.read_bytes() if path.is_file() else b""
    loaded = _read(path)
    say(f"repairing {len(loaded.faces)} faces")
    mesh, remeshed = _repaired(loaded, config, path, say)
    timing = {"repair": time.perf_counter() - t0}
    scale, ext = _scale_and_centre(mesh, config, path)
    rng = np.random.default_rng(config.seed)
    t1 = time.perf_counter()
    say(f"decomposing {len(mesh.faces)} faces into convex pieces (CoACD)")
    hulls = _decompose(mesh, config, root / ".cache" / "coacd")
    timing["decompose"] = time.perf_counter() - t1
    say("sampling antipodal grasps")
    poses, widths, timing["sample"] = _candidates(mesh, rng, config, path)
    root.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}.", dir=root))
    tmp.chmod(0o755)  # mkdtemp's 0700 would hide the object from workers running as another user
    try:
        mesh.export(tmp / "visual.ply")
        (tmp / "collision").mkdir()
        for k, hull in enumerate(hulls):
            hull.export(tmp / "collision" / f"hull_{k:02d}.ply")
        say("finding the rest poses")
        manifest = _manifest(name, path, source_bytes, config, mesh, scale, ext, len(hulls))
        if remeshed is not None:
            manifest["remeshed"] = remeshed
        _write_manifest(tmp, manifest)
        manifest["grasps"], timing["verify"] = _keep_held(tmp, mesh, manifest, poses, widths, config, rng, path, say)
        if preview:
            from kgn_bench.viz.objects import draw_object

            t1 = time.perf_counter()
            draw_object(MeshObject(tmp), tmp / "preview.png")
            timing["preview"] = time.perf_counter() - t1
        timing["total"] = time.perf_counter() - t0
        manifest["timing_s"] = {k: round(v, 3) for k, v in timing.items()}
        manifest["files_sha256"] = content_hashes(tmp)
        _write_manifest(tmp, manifest)
        if target.exists():
            shutil.rmtree(target)
        tmp.rename(target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target
