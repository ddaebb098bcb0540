"""The Primitive Shape (PS) dataset generator: scenes, settling, grasp labels, renders, files.

Every random draw of scene ``i`` comes from ``numpy.random.default_rng([seed, mode_id, i])``, so any
scene can be regenerated alone and the files are identical whatever the number of workers or the backend
(``pool.Backend``: this machine's pool or a Ray cluster). A worker returns a scene's files as bytes
(``scene_files``) and the calling process writes them (``write_scene_files``), so a cluster's workers need no
access to the output folder. A scene whose physics fails (an object leaves the table, the state diverges) is
redrawn from the same stream.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from functools import partial
from itertools import pairwise
from pathlib import Path

import numpy as np

from kgn_bench.camera import REALSENSE, CameraSampler, Intrinsics
from kgn_bench.data.format import (
    FORMAT_VERSION,
    DatasetError,
    ObjectAnnotation,
    SceneAnnotation,
    scene_dir,
    write_view,
)
from kgn_bench.environment import computed_with
from kgn_bench.grasp import GraspSet
from kgn_bench.io import atomic_write_text
from kgn_bench.pool import LOCAL, Backend, run_jobs
from kgn_bench.progress import Progress
from kgn_bench.shapes import PRIMITIVES, TRAIN_DENSITY, GraspDensity, is_known, sample_shape, shape_from_dims
from kgn_bench.sim.appearance import apply_appearance, random_appearance
from kgn_bench.sim.collision import LABEL_VERSION, label_scene
from kgn_bench.sim.depth_noise import DepthNoise
from kgn_bench.sim.placement import PlacementConfig, place_objects, rectify_axisymmetric, settle
from kgn_bench.sim.render import RGBD, SceneRenderer
from kgn_bench.sim.scene import PhysicsError, Scene, SceneObject
from kgn_bench.threads import pin_worker_threads

__all__ = [
    "MODES",
    "GenerateConfig",
    "GeneratedScene",
    "GenerationStats",
    "generate_dataset",
    "generate_scene",
    "relabel_grasps",
    "scene_files",
    "scene_from_annotation",
    "write_scene_files",
]

MODES = ("single", "multi")
TEST_FRACTION = 0.2
MAX_SCENE_ATTEMPTS = 5
MULTI_OBJECTS = 6
"""Objects in a multi-object scene (the PS data's six primitives, one of each)."""
TIMING_KEYS = ("settle", "annotate", "render", "write")
APPEARANCES = ("plain", "random")
"""``GenerateConfig.appearance``'s values."""


@dataclass(frozen=True)
class GenerateConfig:
    """What a dataset is made of. Fields other than ``workers`` define its content (the manifest)."""

    mode: str = "multi"
    scenes: int = 1000
    views: int = 5
    seed: int = 0
    intrinsics: Intrinsics = REALSENSE
    cameras: CameraSampler = field(default_factory=CameraSampler)
    density: GraspDensity = TRAIN_DENSITY
    placement: PlacementConfig = field(default_factory=PlacementConfig)
    objects: tuple[str, ...] = ()
    """The object types scenes draw from; empty: the PS primitives (``PRIMITIVES``)."""
    groups: tuple[int, ...] = ()
    """Sizes of consecutive groups of ``objects`` that are drawn equally often (each object slot picks a group
    uniformly, then one of its objects): ``(6, 299)`` for the primitives and 299 meshes makes half the objects
    primitives. Empty: one group, every object equally often."""
    appearance: str = "plain"
    """``plain``: one uniform random colour per object and the grey table (the paper's data); ``random``:
    procedural textures and colours per object and for the table (``sim.appearance``)."""
    depth_noise: float = 0.0
    """Strength of the benchmark camera's D435-like depth model (``sim.depth_noise.DepthNoise``) applied to the
    stored depth; 0 = the exact render."""

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {self.mode!r}")
        if self.appearance not in APPEARANCES:
            raise ValueError(f"appearance must be one of {', '.join(APPEARANCES)}, got {self.appearance!r}")
        if not (np.isfinite(self.depth_noise) and self.depth_noise >= 0):
            raise ValueError(f"depth_noise must be ≥ 0, got {self.depth_noise}")
        if self.scenes < 1 or self.views < 1 or self.seed < 0:
            raise ValueError("scenes and views must be ≥ 1 and seed ≥ 0")
        for name in self.objects:
            if not is_known(name):
                raise ValueError(f"unknown object {name!r}: neither built in nor imported (kgn-bench objects list)")
        if self.groups and (sum(self.groups) != len(self.objects) or min(self.groups) < 1):
            raise ValueError(f"groups {self.groups} must be positive sizes that add up to the {len(self.objects)} "
                             "objects")
        if self.groups and self.mode == "multi" and len(self.objects) < MULTI_OBJECTS:
            raise ValueError(f"multi mode draws {MULTI_OBJECTS} distinct objects from groups of "
                             f"{len(self.objects)} in all")

    @property
    def object_types(self) -> list[str]:
        return list(self.objects) if self.objects else list(PRIMITIVES)

    def manifest(self) -> dict:
        """The settings that decide the dataset's bytes, written to ``dataset.json``: a folder is resumed only
        by the same manifest. ``kernels`` (``environment.computed_with``) is among them because the settled
        scenes and the renders differ in their last bits between kernel sets (OpenBLAS's), so a resume under
        another set would mix two datasets."""
        return {
            "format_version": FORMAT_VERSION,
            "generator": "kgn_bench.data.generate",
            "mode": self.mode,
            "scenes": self.scenes,
            "views": self.views,
            "seed": self.seed,
            "intrinsics": self.intrinsics.to_dict(),
            "camera_distance_m": list(self.cameras.distance_range),
            "camera_elevation_deg": [float(np.rad2deg(a)) for a in self.cameras.elevation_range],
            "grasp_density": {"translations": self.density.translations, "angles": self.density.angles},
            "label_version": LABEL_VERSION,
            "kernels": computed_with(),
            "object_types": self.object_types,
            "test_fraction": TEST_FRACTION,
            # at their defaults these stay out, so that datasets made before they existed keep their identity
            **({"appearance": self.appearance} if self.appearance != "plain" else {}),
            **({"depth_noise": self.depth_noise} if self.depth_noise else {}),
            **({"object_groups": list(self.groups)} if len(self.groups) > 1 else {}),
        }

    def rng(self, index: int, stream: int | None = None) -> np.random.Generator:
        """Scene ``index``'s generator; ``stream`` (1: appearance, 2: depth noise) is a separate one, so that
        turning either on leaves the scenes, cameras and labels as they were."""
        key = [self.seed, MODES.index(self.mode), index] + ([] if stream is None else [stream])
        return np.random.default_rng(key)

    def split(self) -> tuple[list[int], list[int]]:
        """Scene-wise (train, test) split: a seeded permutation, the first 20 % go to test."""
        perm = np.random.default_rng([self.seed, MODES.index(self.mode), 2**31]).permutation(self.scenes)
        n_test = round(TEST_FRACTION * self.scenes)
        return sorted(perm[n_test:].tolist()), sorted(perm[:n_test].tolist())


@dataclass
class GeneratedScene:
    annotation: SceneAnnotation
    views: list[RGBD]
    timings: dict[str, float]


def _draw_names(config: GenerateConfig, rng: np.random.Generator) -> list[str]:
    """The scene's object names: one (single mode) or ``MULTI_OBJECTS`` distinct ones in random order (multi
    mode: all six primitives, or six of the given objects); with ``groups``, each slot picks a group that has
    objects left uniformly, then one of them uniformly."""
    names = config.object_types
    count = 1 if config.mode == "single" else MULTI_OBJECTS
    if len(config.groups) > 1:
        bounds = np.cumsum((0, *config.groups))
        left = [list(names[a:b]) for a, b in pairwise(bounds)]
        chosen = []
        for _ in range(count):
            open_groups = [g for g in left if g]
            group = open_groups[rng.integers(len(open_groups))]
            chosen.append(group.pop(int(rng.integers(len(group)))))
        return chosen
    if config.mode == "single":
        return [names[rng.integers(len(names))]]
    if len(names) <= MULTI_OBJECTS:
        return [names[k] for k in rng.permutation(len(names))]
    return [names[k] for k in rng.choice(len(names), MULTI_OBJECTS, replace=False)]


def _sample_objects(config: GenerateConfig, rng: np.random.Generator) -> list[SceneObject]:
    """The scene's objects (``_draw_names``), each with its random dimensions and colour."""
    return [SceneObject(sample_shape(n, rng), tuple(float(c) for c in rng.uniform(0.0, 1.0, 3)))
            for n in _draw_names(config, rng)]


def generate_scene(config: GenerateConfig, index: int) -> GeneratedScene:
    """Build, settle, annotate and render scene ``index`` (deterministic in ``config`` and ``index``)."""
    rng = config.rng(index)
    t0 = time.perf_counter()
    for attempt in range(MAX_SCENE_ATTEMPTS):
        objects = _sample_objects(config, rng)
        extend = None
        if config.appearance == "random":
            looks = random_appearance(len(objects), config.rng(index, 1 + 10 * attempt))
            extend = partial(apply_appearance, appearance=looks)
        scene = Scene(objects, config.intrinsics, extend=extend)
        try:
            place_objects(scene, rng, config.placement)
            settle(scene, config.placement)
        except PhysicsError as e:
            if attempt == MAX_SCENE_ATTEMPTS - 1:
                raise PhysicsError(f"scene {index}: {e} (after {MAX_SCENE_ATTEMPTS} attempts)") from None
            continue
        break
    rectify_axisymmetric(scene)
    t1 = time.perf_counter()
    grasps = label_scene(scene, config.density)
    t2 = time.perf_counter()
    camera_poses = config.cameras.sample(rng, config.views)
    with SceneRenderer(scene) as renderer:
        views = [renderer.render(p) for p in camera_poses]
    if config.depth_noise:
        noise, noise_rng = DepthNoise(config.depth_noise), config.rng(index, 2)
        for v in views:
            v.depth = noise.apply(v.depth, config.intrinsics.fx, noise_rng)
    t3 = time.perf_counter()
    annotation = SceneAnnotation(
        index=index,
        intrinsics=config.intrinsics,
        camera_poses=camera_poses,
        objects=[
            ObjectAnnotation(o.shape.name, o.shape.dims(), scene.object_pose(i), o.color, o.shape.mass(), g)
            for i, (o, g) in enumerate(zip(objects, grasps))
        ],
        density=config.density,
    )
    return GeneratedScene(annotation, views, {"settle": t1 - t0, "annotate": t2 - t1, "render": t3 - t2})


def write_scene(root: Path, generated: GeneratedScene) -> float:
    """Write a scene folder atomically (temporary folder, then rename); returns the seconds spent."""
    t0 = time.perf_counter()
    write_scene_files(root, generated.annotation.index, scene_files(generated))
    return time.perf_counter() - t0


def scene_files(generated: GeneratedScene) -> dict[str, bytes]:
    """The files of a scene folder (name → content): the encoded views and ``scene.json``."""
    with tempfile.TemporaryDirectory(prefix="kgn-scene-") as tmp:
        for v, rgbd in enumerate(generated.views):
            write_view(Path(tmp), v, rgbd)
        files = {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir())}
    files["scene.json"] = json.dumps(generated.annotation.to_json()).encode()
    return files


def write_scene_files(root: Path, index: int, files: dict[str, bytes]) -> None:
    """Write scene ``index``'s folder atomically (temporary folder, then rename)."""
    final = scene_dir(root, index)
    tmp = final.parent / f".tmp-{final.name}-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    for name, data in files.items():
        (tmp / name).write_bytes(data)
    if final.exists():
        shutil.rmtree(final)
    os.replace(tmp, final)


def scene_from_annotation(annotation: SceneAnnotation) -> Scene:
    """Rebuild the simulator scene of an annotation with every object at its recorded pose."""
    objects = [
        SceneObject(shape_from_dims(o.type, o.dims), o.color, o.pose)
        for o in annotation.objects
    ]
    return Scene(objects, annotation.intrinsics)


def relabel_grasps(annotation: SceneAnnotation, density: GraspDensity) -> list[GraspSet]:
    """Grasp families of a stored scene regenerated at ``density`` (e.g. ``EVAL_DENSITY``, 10 / 30) and
    collision-labelled exactly as at generation time."""
    return label_scene(scene_from_annotation(annotation), density)


# -- the dataset --------------------------------------------------------------------------------


@dataclass
class GenerationStats:
    scenes: int
    views: int
    wall: float
    timings: dict[str, float]

    @property
    def views_per_second(self) -> float:
        return self.views / self.wall if self.wall > 0 else float("nan")


def _generate_files(args: tuple[GenerateConfig, int]) -> tuple[int, dict[str, bytes], dict[str, float]]:
    """A worker's job: scene ``index`` generated and encoded; the caller writes the files."""
    config, index = args
    generated = generate_scene(config, index)
    t0 = time.perf_counter()
    files = scene_files(generated)
    return index, files, {**generated.timings, "write": time.perf_counter() - t0}


def _worker_init() -> None:
    pin_worker_threads()  # one thread per library: the workers already fill the cores


def prepare_output(config: GenerateConfig, root: Path, overwrite: bool) -> list[int]:
    """Check or create the output folder; returns the scene indices still to generate.

    A folder holding this very dataset (same manifest) is resumed; a non-empty folder holding anything
    else is refused unless ``overwrite``, which removes only the dataset's own files.
    """
    root = Path(root)
    manifest = config.manifest()
    if root.exists() and not root.is_dir():
        raise DatasetError(f"output {root} exists and is not a folder")
    if root.is_dir() and any(root.iterdir()):
        existing = None
        if (root / "dataset.json").is_file():
            try:
                existing = json.loads((root / "dataset.json").read_text())
            except json.JSONDecodeError:
                existing = None
        if overwrite:
            for name in ("dataset.json", "train.txt", "test.txt"):
                (root / name).unlink(missing_ok=True)
            shutil.rmtree(root / "scenes", ignore_errors=True)
        elif existing is None:
            raise DatasetError(
                f"output folder {root} is not empty and holds no dataset; use --overwrite or another folder"
            )
        elif existing != manifest:
            diff = [k for k in manifest if existing.get(k) != manifest[k]]
            raise DatasetError(
                f"output folder {root} holds a dataset with other settings ({', '.join(diff)}); "
                "use --overwrite or another folder"
            )
    (root / "scenes").mkdir(parents=True, exist_ok=True)
    for stale in (root / "scenes").glob(".tmp-*"):
        shutil.rmtree(stale, ignore_errors=True)
    if not (root / "dataset.json").is_file():
        atomic_write_text(root / "dataset.json", json.dumps(manifest, indent=2) + "\n")
    return [i for i in range(config.scenes) if not (scene_dir(root, i) / "scene.json").is_file()]


def generate_dataset(config: GenerateConfig, root: Path, workers: int = 1, overwrite: bool = False,
                     progress: bool = True, backend: Backend = LOCAL) -> GenerationStats:
    """Generate (or finish) the dataset in ``root`` with ``workers`` processes (or, on a Ray ``backend``,
    ``workers`` scenes in flight); writes the split last."""
    if workers < 1:
        raise ValueError("workers must be ≥ 1")
    root = Path(root)
    backend.prepare(_worker_init, (), workers)()  # a cluster that cannot run the scenes fails here, before any write
    todo = prepare_output(config, root, overwrite)
    totals = dict.fromkeys(TIMING_KEYS, 0.0)
    bar = Progress(len(todo), f"data generate {config.mode}", unit="scenes", enabled=progress)
    start = time.perf_counter()
    jobs = [(config, i) for i in todo]

    def finished(result: tuple[int, dict[str, bytes], dict[str, float]]) -> None:
        index, files, timings = result
        t0 = time.perf_counter()
        write_scene_files(root, index, files)
        timings = {**timings, "write": timings["write"] + time.perf_counter() - t0}
        for k, v in timings.items():
            totals[k] += v
        bar.update()

    run_jobs(jobs, _generate_files, finished, workers=workers, initializer=_worker_init,
             what=f"data generation into {root}", backend=backend)
    wall = time.perf_counter() - start
    train, test = config.split()
    atomic_write_text(root / "train.txt", "".join(f"{i}\n" for i in train))
    atomic_write_text(root / "test.txt", "".join(f"{i}\n" for i in test))
    return GenerationStats(scenes=len(todo), views=len(todo) * config.views, wall=wall, timings=totals)
