"""The paper's vision metrics: grasp success rate (GSR), grasp coverage rate (GCR) and object success rate
(OSR) at three (translation, rotation) error thresholds, as defined by the reference implementation.

Frames and units: every pose here is a world-frame grasp pose ``T_world_grasp`` (4×4, grasp frame of
``kgn_bench.grasp``). Translations are in metres, angles in radians (degrees only in text). The predicted width is not
evaluated.

Matching: prediction p matches ground-truth (GT) grasp g at threshold (δ, θ) iff, both strictly,

    ‖t_p − t_g‖ < δ   and   min(d_R(R_p, R_g), d_R(R_p, R_g·diag(1, −1, −1))) < θ,

with d_R(A, B) = arccos(clip((tr(AᵀB) − 1) / 2, −1, 1)) (``geometry.rotation_angle``). The second term
makes a grasp and the same grasp turned 180° about its approach axis the same grasp.

Ground truth of an image: for each object of its scene, the collision-free grasps of its families
regenerated at ``EVAL_DENSITY`` (10 translations / 30 unique angles) and collision-labelled as at
generation (``data.generate.relabel_grasps``). Objects without a collision-free grasp are skipped.

Crediting, per image and threshold, objects in scene order i = 0, 1, …:

    n_succ,i = #{predictions matching a GT grasp of i and no GT grasp of an object before i}
    n_cov,i  = #{GT grasps of i matched by at least one prediction}

so a prediction matching two touching objects counts once, for the first. Metrics pool the counts over
images (they are never averaged per image):

    GSR = Σ n_succ / Σ N_pred,   GCR = Σ n_cov / Σ n_GT,   OSR = #{objects: n_succ ≥ 1} / #{objects: n_GT > 0}.

A rate whose denominator is 0 (GSR when no prediction was made at all, a shape absent from the data) is
undefined: ``None`` in dicts and JSON, "n/a" in text. It is never reported as 0.

Per shape (this fixes the reference implementation's per-type GSR, whose denominator was every prediction
of the image): each prediction is *attributed* to one object per threshold, namely

* the object it is credited to, if any;
* otherwise the object owning the GT grasp nearest to it in translation among all the image's labelled
  grasps, colliding ones included (so an object without free grasps still receives the predictions made
  on it, and they count as failures of its shape).

Per-shape GSR = predictions credited to objects of the shape / predictions attributed to the shape. The
per-shape denominators plus ``unattributed`` (predictions of images that have no labelled grasp at all)
sum to N_pred at every threshold. Per-shape GCR and OSR restrict the sums above to the shape's objects.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from kgn_bench.detectors.base import Candidates, Detector, Observation
from kgn_bench.eval.views import detector_call, iter_views
from kgn_bench.grasp import GraspSet, grasp_rotation_error
from kgn_bench.progress import Progress
from kgn_bench.shapes import EVAL_DENSITY, OBJECTS, PRIMITIVES, GraspDensity, is_known

if TYPE_CHECKING:
    from kgn_bench.model.checkpoint import LoadedModel

__all__ = [
    "MESH",
    "SHAPES",
    "THRESHOLDS",
    "ImageCounts",
    "Threshold",
    "VisionMetrics",
    "evaluate_dataset",
    "evaluate_image",
    "grasp_matches",
    "held_out_evaluator",
    "nearest_grasps",
    "pose_errors",
    "shape_column",
]

MESH = "mesh"
"""The per-shape column that pools every imported mesh object (``kgn-bench objects add``)."""
SHAPES: tuple[str, ...] = (*PRIMITIVES, MESH)
"""The per-shape figures' columns, in order: the PS primitives, then ``MESH`` for all imported objects."""


def shape_column(object_type: str) -> str:
    """The per-shape column of an object type: a primitive's own, ``MESH`` for an imported object."""
    if object_type in PRIMITIVES:
        return object_type
    if object_type not in OBJECTS and is_known(object_type):
        return MESH
    raise ValueError(f"unknown object type {object_type!r}; known: {', '.join(PRIMITIVES)} and imported objects")

_COUNT_FIELDS = ("attributed", "credited", "covered", "gt", "objects_succeeded", "objects_evaluated")


@dataclass(frozen=True)
class Threshold:
    """A match threshold: ``translation`` in metres and ``rotation`` in radians (both strict upper bounds)."""

    translation: float
    rotation: float

    def __post_init__(self) -> None:
        if not (self.translation > 0.0 and self.rotation > 0.0):
            raise ValueError(f"thresholds must be positive, got {self.translation} m and {self.rotation} rad")

    @property
    def label(self) -> str:
        """E.g. ``"2 cm / 30°"``."""
        return f"{self.translation * 100.0:.3g} cm / {math.degrees(self.rotation):.3g}°"


THRESHOLDS: tuple[Threshold, ...] = (
    Threshold(0.01, math.radians(20.0)),
    Threshold(0.02, math.radians(30.0)),
    Threshold(0.03, math.radians(45.0)),
)
"""The paper's three passes: (1 cm, 20°), (2 cm, 30°), (3 cm, 45°)."""


# -- matching -----------------------------------------------------------------------------------


def pose_errors(pred: np.ndarray, gt: np.ndarray, max_translation: float = math.inf) -> tuple[np.ndarray, np.ndarray]:
    """Errors between every prediction ``pred`` (N, 4, 4) and GT grasp ``gt`` (M, 4, 4), same frame.

    Returns ``(d_t, d_R)``, each (N, M): d_t = ‖t_p − t_g‖ in metres and the symmetric rotation error
    d_R = min(d_R(R_p, R_g), d_R(R_p, R_g·diag(1, −1, −1))) in radians. To save time d_R is computed only
    for pairs with d_t < ``max_translation`` and is +inf elsewhere.
    """
    d_t = np.linalg.norm(pred[:, None, :3, 3] - gt[None, :, :3, 3], axis=-1)
    d_r = np.full(d_t.shape, np.inf)
    i, j = np.nonzero(d_t < max_translation)
    if len(i):
        Rp, Rg = pred[i, :3, :3], gt[j, :3, :3]
        d_r[i, j] = grasp_rotation_error(Rp, Rg)
    return d_t, d_r


def nearest_grasps(pred: np.ndarray, gt: GraspSet) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For predictions ``pred`` (N, 4, 4) and labelled grasps ``gt`` (same frame): ``(d_t, d_r, nearest,
    matched)``: the (N, M) errors of ``pose_errors``, the index of each prediction's nearest grasp (least
    d_t/δ + d_R/θ at the first threshold) and whether it lies within that threshold of a collision-free one."""
    first = THRESHOLDS[0]
    d_t, d_r = pose_errors(pred, gt.poses)
    nearest = np.argmin(d_t / first.translation + d_r / first.rotation, axis=1)
    matched = ((d_t < first.translation) & (d_r < first.rotation) & ~gt.collides[None, :]).any(axis=1)
    return d_t, d_r, nearest, matched


def grasp_matches(pred: np.ndarray, gt: np.ndarray, threshold: Threshold) -> np.ndarray:
    """(N, M) bool: prediction n matches GT grasp m (d_t < δ and symmetric d_R < θ, both strict)."""
    d_t, d_r = pose_errors(pred, gt, threshold.translation)
    return (d_t < threshold.translation) & (d_r < threshold.rotation)


# -- counts -------------------------------------------------------------------------------------


@dataclass(eq=False)
class ImageCounts:
    """Integer counts of one or more images; ``a + b`` pools two sets of images exactly.

    ``images`` and ``predictions`` (N_pred) are totals; ``unattributed`` counts predictions of images
    without any labelled grasp. Every other field is an int64 array (T, S) over thresholds × ``SHAPES``:
    ``attributed`` predictions (per-shape GSR denominator), ``credited`` predictions (Σ n_succ),
    ``covered`` GT grasps (Σ n_cov), ``gt`` collision-free GT grasps (Σ n_GT, the same on every row),
    ``objects_succeeded`` (n_succ ≥ 1) and ``objects_evaluated`` (n_GT > 0).
    """

    thresholds: tuple[Threshold, ...]
    images: int
    predictions: int
    unattributed: int
    attributed: np.ndarray
    credited: np.ndarray
    covered: np.ndarray
    gt: np.ndarray
    objects_succeeded: np.ndarray
    objects_evaluated: np.ndarray

    def __post_init__(self) -> None:
        self.thresholds = tuple(self.thresholds)
        shape = (len(self.thresholds), len(SHAPES))
        for name in _COUNT_FIELDS:
            value = np.asarray(getattr(self, name), dtype=np.int64)
            if value.shape != shape:
                raise ValueError(f"count array {name} must have shape {shape}, got {value.shape}")
            setattr(self, name, value)

    @classmethod
    def zeros(cls, thresholds: Sequence[Threshold] = THRESHOLDS) -> ImageCounts:
        """No image yet."""
        shape = (len(tuple(thresholds)), len(SHAPES))
        return cls(tuple(thresholds), 0, 0, 0, **{name: np.zeros(shape, dtype=np.int64) for name in _COUNT_FIELDS})

    def __add__(self, other: ImageCounts) -> ImageCounts:
        if not isinstance(other, ImageCounts):
            return NotImplemented
        if other.thresholds != self.thresholds:
            raise ValueError("cannot add counts evaluated at different thresholds")
        return ImageCounts(
            self.thresholds,
            self.images + other.images,
            self.predictions + other.predictions,
            self.unattributed + other.unattributed,
            **{name: getattr(self, name) + getattr(other, name) for name in _COUNT_FIELDS},
        )

    def to_dict(self) -> dict:
        """JSON-serialisable form (for worker processes and files); ``from_dict`` reads it back exactly."""
        return {
            "thresholds": [[t.translation, t.rotation] for t in self.thresholds],
            "shapes": list(SHAPES),
            "images": self.images,
            "predictions": self.predictions,
            "unattributed": self.unattributed,
            **{name: getattr(self, name).tolist() for name in _COUNT_FIELDS},
        }

    @classmethod
    def from_dict(cls, d: dict) -> ImageCounts:
        shapes = list(d.get("shapes", []))
        if shapes == list(PRIMITIVES):  # stored before the mesh column existed: no mesh object in it
            d = {**d, **{name: [[*row, 0] for row in d[name]] for name in _COUNT_FIELDS}}
        elif shapes != list(SHAPES):
            raise ValueError(f"counts are for shapes {d.get('shapes')}, expected {list(SHAPES)}")
        return cls(
            tuple(Threshold(float(a), float(b)) for a, b in d["thresholds"]),
            int(d["images"]),
            int(d["predictions"]),
            int(d["unattributed"]),
            **{name: np.asarray(d[name], dtype=np.int64) for name in _COUNT_FIELDS},
        )


def _shape_indices(object_types: Sequence[str]) -> np.ndarray:
    return np.array([SHAPES.index(shape_column(t)) for t in object_types], dtype=np.int64)


def evaluate_image(
    pred_world_poses: np.ndarray,
    gt_per_object: Sequence[GraspSet],
    object_types: Sequence[str],
    thresholds: Sequence[Threshold] = THRESHOLDS,
) -> ImageCounts:
    """Counts of one image (module docstring for the rules).

    ``pred_world_poses`` (N, 4, 4): predicted ``T_world_grasp``. ``gt_per_object``: per object in scene
    order, its labelled GT grasps in the world frame (``collides`` marks the ones excluded from matching).
    ``object_types``: per object, a name from ``SHAPES``.
    """
    pred = np.asarray(pred_world_poses, dtype=float)
    if pred.ndim != 3 or pred.shape[1:] != (4, 4):
        raise ValueError(f"predicted poses must be (N, 4, 4), got {pred.shape}")
    if not np.all(np.isfinite(pred)):
        raise ValueError("predicted poses must be finite")
    if len(gt_per_object) != len(object_types):
        raise ValueError(f"{len(gt_per_object)} GT grasp sets for {len(object_types)} object types")
    shape_of = _shape_indices(object_types)
    thresholds = tuple(thresholds)
    n_obj, n_pred = len(object_types), len(pred)
    counts = ImageCounts.zeros(thresholds)
    counts.images, counts.predictions = 1, n_pred

    gt = GraspSet.concatenate(list(gt_per_object))
    owner = np.repeat(np.arange(n_obj), np.array([len(g) for g in gt_per_object], dtype=np.int64))
    free = ~gt.collides
    n_gt = np.bincount(owner[free], minlength=n_obj)
    evaluated = n_gt > 0
    for k in range(len(thresholds)):
        np.add.at(counts.gt[k], shape_of, n_gt)
        np.add.at(counts.objects_evaluated[k], shape_of, evaluated.astype(np.int64))
    if n_pred == 0:
        return counts
    if len(gt) == 0:
        counts.unattributed = n_pred
        return counts

    d_t, d_r = pose_errors(pred, gt.poses, max(t.translation for t in thresholds))
    nearest = owner[np.argmin(d_t, axis=1)]
    for k, th in enumerate(thresholds):
        match = (d_t < th.translation) & (d_r < th.rotation) & free[None, :]
        per_object = np.zeros((n_pred, n_obj), dtype=bool)  # prediction n matches a free GT grasp of object i
        rows, cols = np.nonzero(match)
        per_object[rows, owner[cols]] = True
        hit = per_object.any(axis=1)
        first = np.argmax(per_object, axis=1)  # the earliest object in scene order each prediction matches
        n_succ = np.bincount(first[hit], minlength=n_obj)
        n_cov = np.bincount(owner[match.any(axis=0)], minlength=n_obj)
        attributed_to = np.where(hit, first, nearest)
        np.add.at(counts.attributed[k], shape_of[attributed_to], 1)
        np.add.at(counts.credited[k], shape_of, n_succ)
        np.add.at(counts.covered[k], shape_of, n_cov)
        np.add.at(counts.objects_succeeded[k], shape_of, (evaluated & (n_succ > 0)).astype(np.int64))
    return counts


# -- summaries ----------------------------------------------------------------------------------


def _rate(num: int, den: int) -> float | None:
    return None if den == 0 else num / den


def _pct(rate: float | None) -> str:
    return "n/a" if rate is None else f"{100.0 * rate:.1f}"


def _figures(credited: int, predictions: int, covered: int, gt: int, succeeded: int, objects: int) -> dict:
    return {
        "gsr": _rate(credited, predictions),
        "gcr": _rate(covered, gt),
        "osr": _rate(succeeded, objects),
        "credited": credited,
        "predictions": predictions,
        "covered": covered,
        "gt_grasps": gt,
        "objects_succeeded": succeeded,
        "objects": objects,
    }


@dataclass
class VisionMetrics:
    """Accumulated counts of evaluated images and the seconds spent (``detect``, ``ground_truth``,
    ``match``, ``read``), with the rates as a JSON-ready dict and as Markdown."""

    counts: ImageCounts
    seconds: dict[str, float] = field(default_factory=dict)

    @classmethod
    def empty(cls, thresholds: Sequence[Threshold] = THRESHOLDS) -> VisionMetrics:
        return cls(ImageCounts.zeros(thresholds))

    def add(self, counts: ImageCounts) -> None:
        self.counts = self.counts + counts

    def summarise(self) -> dict:
        """Rates in [0, 1] (``None`` where the denominator is 0) and the counts behind them, per threshold
        and per shape; JSON-serialisable."""
        c = self.counts
        rows = []
        for k, th in enumerate(c.thresholds):
            row = {"label": th.label, "translation_m": th.translation,
                   "rotation_deg": round(math.degrees(th.rotation), 9)}
            row.update(_figures(int(c.credited[k].sum()), c.predictions, int(c.covered[k].sum()),
                                int(c.gt[k].sum()), int(c.objects_succeeded[k].sum()),
                                int(c.objects_evaluated[k].sum())))
            row["per_shape"] = {
                s: _figures(int(c.credited[k, j]), int(c.attributed[k, j]), int(c.covered[k, j]), int(c.gt[k, j]),
                            int(c.objects_succeeded[k, j]), int(c.objects_evaluated[k, j]))
                for j, s in enumerate(SHAPES)
            }
            rows.append(row)
        return {
            "images": c.images,
            "predictions": c.predictions,
            "unattributed_predictions": c.unattributed,
            "thresholds": rows,
            "seconds": {k: float(v) for k, v in self.seconds.items()},
            "note": "rates are fractions; null where the denominator is 0 (GSR without any prediction)",
        }

    def to_markdown(self) -> str:
        """A table of GSR / GCR / OSR (%) per threshold, then one per shape."""
        s = self.summarise()
        lines = [
            f"Vision metrics over {s['images']} images, {s['predictions']} predictions "
            "(rates in %, n/a = no denominator).",
            "",
            "| threshold | GSR % | GCR % | OSR % | credited / predictions | covered / GT grasps | objects |",
            "|---|---:|---:|---:|---:|---:|---:|",
        ]
        for r in s["thresholds"]:
            lines.append(
                f"| {r['label']} | {_pct(r['gsr'])} | {_pct(r['gcr'])} | {_pct(r['osr'])} "
                f"| {r['credited']} / {r['predictions']} | {r['covered']} / {r['gt_grasps']} "
                f"| {r['objects_succeeded']} / {r['objects']} |"
            )
        lines += [
            "",
            "Per shape: GSR / GCR / OSR (%); a prediction is attributed to the object it is credited to, "
            "else to the object of its nearest GT grasp.",
            "",
            "| shape | " + " | ".join(r["label"] for r in s["thresholds"]) + " | objects | GT grasps |",
            "|---|" + "---:|" * (len(s["thresholds"]) + 2),
        ]
        for shape in SHAPES:
            if shape == MESH and s["thresholds"] and not s["thresholds"][0]["per_shape"][shape]["objects"]:
                continue  # no imported object in the images
            cells = [
                " / ".join(_pct(r["per_shape"][shape][m]) for m in ("gsr", "gcr", "osr")) for r in s["thresholds"]
            ]
            first = s["thresholds"][0]["per_shape"][shape] if s["thresholds"] else {"objects": 0, "gt_grasps": 0}
            lines.append(f"| {shape} | " + " | ".join(cells) + f" | {first['objects']} | {first['gt_grasps']} |")
        if s["unattributed_predictions"]:
            lines += ["", f"{s['unattributed_predictions']} predictions came from images without ground truth."]
        return "\n".join(lines) + "\n"


# -- the dataset --------------------------------------------------------------------------------


def evaluate_dataset(
    detect: Detector | Callable[[Observation], Candidates],
    data_dir: Path,
    split: str = "test",
    views: int | None = None,
    thresholds: Sequence[Threshold] = THRESHOLDS,
    density: GraspDensity = EVAL_DENSITY,
    progress: bool = True,
) -> VisionMetrics:
    """Run a detector on every view of a split's scenes and accumulate the vision metrics.

    ``detect`` is a ``Detector`` (its ``reset([scene, view])`` is called before each image, so seeded
    detectors are deterministic) or any callable ``Observation -> Candidates`` (camera-frame poses). Each
    view becomes an ``Observation`` (RGB, depth, intrinsics, camera pose: no mask); candidates go to the
    world frame as ``camera_pose @ T_cam_grasp``. Ground truth is regenerated once per scene at
    ``density``. ``views`` caps the total number of images (scenes in split order, views in order).
    """
    run = detector_call(detect)
    seconds = dict.fromkeys(("read", "ground_truth", "detect", "match"), 0.0)
    total, items = iter_views(data_dir, split, views, density, seconds)
    metrics = VisionMetrics.empty(thresholds)
    bar = Progress(total, f"eval vision {split}", unit="images", enabled=progress)
    middle = len(metrics.counts.thresholds) // 2
    for item in items:
        t1 = time.perf_counter()
        candidates = run(item)
        t2 = time.perf_counter()
        metrics.add(evaluate_image(candidates.world_poses(item.observation.camera_pose), item.gt, item.types,
                                   thresholds))
        seconds["detect"] += t2 - t1
        seconds["match"] += time.perf_counter() - t2
        c = metrics.counts
        gsr = _rate(int(c.credited[middle].sum()), c.predictions)
        bar.update(extra=f"GSR@{c.thresholds[middle].label} {_pct(gsr)}%")
    metrics.seconds = seconds
    return metrics


def held_out_evaluator(model: LoadedModel, data: Path, views: int) -> dict:
    """The training driver's held-out check (``training.train.HeldOutEvaluator``): ``model`` decoded by
    ``detectors.kgn.KGNDetector`` under its own variant, scored on the first ``views`` views of the ``test``
    split of ``data`` without a progress bar; returns ``VisionMetrics.summarise()``."""
    from kgn_bench.detectors.kgn import KGNDetector

    detector = KGNDetector(model.variant.name, model=model)
    return evaluate_dataset(detector, data, split="test", views=views, progress=False).summarise()
