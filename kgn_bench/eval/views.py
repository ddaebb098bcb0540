"""The test views of a dataset split with their ground truth, and a detector as a function of one view:
what every held-out evaluation (``eval.vision``, ``eval.errors``, ``eval.physics_check``) iterates over.

Frames: ``TestView.observation.camera_pose`` is ``T_world_cam`` (OpenCV camera frame, ``kgn_bench.camera``);
the ground-truth grasps are world-frame ``T_world_grasp`` poses, collision-labelled as at generation
(``data.generate.relabel_grasps``) at the requested ``GraspDensity``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from kgn_bench.data.format import DatasetError, SceneAnnotation, read_manifest, read_split, read_view, scene_dir
from kgn_bench.data.generate import relabel_grasps
from kgn_bench.detectors.base import Candidates, Detector, Observation
from kgn_bench.grasp import GraspSet
from kgn_bench.shapes import EVAL_DENSITY, GraspDensity

__all__ = ["TestView", "detector_call", "iter_views"]


@dataclass
class TestView:
    """One image of a split with its ground truth: the ``Observation`` (RGB, depth, intrinsics, camera
    pose; no mask), the scene's GT grasps per object (world frame, collision-labelled), object types, and the
    objects' annotations (type, dims, world pose)."""

    scene: int
    view: int
    observation: Observation
    gt: list[GraspSet]
    types: list[str]
    objects: list = field(default_factory=list)


def iter_views(data_dir: Path, split: str = "test", views: int | None = None, density: GraspDensity = EVAL_DENSITY,
               seconds: dict[str, float] | None = None):
    """The split's images in order (scenes in split order, views in order), at most ``views`` of them, and
    the number that will come: ``(total, generator of TestView)``. Ground truth is regenerated once per scene
    at ``density``; ``seconds`` (if given) accumulates ``read`` and ``ground_truth`` time."""
    root = Path(data_dir)
    manifest = read_manifest(root)
    scenes = read_split(root, split)
    if not scenes:
        raise DatasetError(f"split {split!r} of {root} has no scenes")
    if views is not None and views < 1:
        raise ValueError(f"views must be ≥ 1, got {views}")
    available = len(scenes) * int(manifest.get("views", 1))
    total = available if views is None else min(views, available)
    clock = seconds if seconds is not None else {}

    def generate():
        done = 0
        for scene in scenes:
            if done >= total:
                return
            folder = scene_dir(root, scene)
            t0 = time.perf_counter()
            annotation = SceneAnnotation.load(folder / "scene.json")
            t1 = time.perf_counter()
            gt = relabel_grasps(annotation, density)
            clock["read"] = clock.get("read", 0.0) + t1 - t0
            clock["ground_truth"] = clock.get("ground_truth", 0.0) + time.perf_counter() - t1
            types = [o.type for o in annotation.objects]
            for view in range(len(annotation.camera_poses)):
                if done >= total:
                    return
                t0 = time.perf_counter()
                rgbd = read_view(folder, view)
                obs = Observation(rgbd.rgb, rgbd.depth, annotation.intrinsics, annotation.camera_poses[view])
                clock["read"] = clock.get("read", 0.0) + time.perf_counter() - t0
                done += 1
                yield TestView(scene, view, obs, gt, types, annotation.objects)

    return total, generate()


def detector_call(detect: Detector | Callable[[Observation], Candidates]) -> Callable[[TestView], Candidates]:
    """``detect`` as a function of a ``TestView``: a ``Detector`` is reset with ``[scene, view]`` first (so
    seeded detectors are deterministic), a plain callable is called; anything but ``Candidates`` is an error."""
    if isinstance(detect, Detector):
        call, reset = detect.detect, detect.reset
    elif callable(detect):
        call, reset = detect, None
    else:
        raise TypeError(f"detect must be a Detector or a callable, got {type(detect).__name__}")

    def run(item: TestView) -> Candidates:
        if reset is not None:
            reset([item.scene, item.view])
        candidates = call(item.observation)
        if not isinstance(candidates, Candidates):
            raise TypeError(f"the detector returned {type(candidates).__name__}, expected Candidates")
        return candidates

    return run
