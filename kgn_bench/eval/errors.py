"""Where the 1 cm misses come from: each prediction's error against its nearest ground-truth grasp, split
into the terms the network predicts separately.

Frames: the grasp centres of a prediction ``p`` and of its nearest GT grasp ``g`` are taken in the
camera frame (OpenCV axes, ``T_cam_grasp = T_world_cam⁻¹ · T_world_grasp``). The nearest GT grasp (free or
colliding, of any object of the image) minimises ``d_t / δ + d_R / θ`` at the first threshold (1 cm, 20°),
so it is the one the prediction came closest to matching. The terms:

* **centre (image plane)**: the pixel distance between the projections of ``p`` and ``g``, and the same
  distance as a length at the GT grasp's depth, ``e_⊥ = px · z_g / f`` (cm): what the heatmap peak, the
  sub-pixel offset and the keypoints decide;
* **distance along the ray**: ``e_∥ = ‖p‖ − ‖g‖`` (cm): what the scale head (or, for KGN, PnP's translation)
  decides;
* **rotation**: the symmetric geodesic angle ``d_R`` (degrees, the 180° flip about the approach is the same
  grasp): what the orientation bin and the keypoints decide;
* **width**: ``w_p − w_g`` (cm). The vision metrics do not score the width; it is reported because the closed
  loop uses it;
* **keypoints** (keypoint detectors only): for each of the 4 box keypoints (L, R, TL, TR), the pixel distance
  between the detector's keypoint (``Candidates.keypoints``, the network's output before PnP) and the
  projection of the nearest GT grasp's box keypoints, the box of the detector's variant at the GT grasp's
  distance (``Variant.box_sides``); of the GT grasp's two forms (the 180° flip swaps L with R and TL with TR)
  the one nearer on average. This is the error PnP turns into a pose error (the paper's Fig. 2,
  ``eval.pnp_noise``).

"Share of 1 cm failures each term alone would cause": the fraction of predictions that would fail the
(1 cm, 20°) match with that term's error alone (``|e_⊥| ≥ 1 cm``, ``|e_∥| ≥ 1 cm``, ``d_R ≥ 20°``), and the
same fraction among the predictions that do fail. Predictions are attributed to the shape of the nearest GT
grasp's object.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kgn_bench.geometry import invert_pose, project, transform_points
from kgn_bench.grasp import KEYPOINT_NAMES, GraspSet, flip_180, keypoints_in_frame
from kgn_bench.io import atomic_write_text
from kgn_bench.progress import Progress
from kgn_bench.types import Candidates, Observation

from .views import detector_call, iter_views
from .vision import SHAPES, nearest_grasps, shape_column

__all__ = ["KEYPOINT_TERMS", "TERMS", "ErrorTable", "cdf_figure", "decompose_dataset", "decompose_image",
           "grasp_errors", "keypoint_errors", "markdown", "write_errors"]

TERMS = ("centre_px", "centre_cm", "ray_cm", "rotation_deg", "width_cm")
"""The columns of each prediction's error row."""
KEYPOINT_TERMS = tuple(f"{name}_px" for name in KEYPOINT_NAMES)
"""The per-keypoint columns (pixels; NaN for a detector without keypoints)."""
_LIMITS = {"centre_cm": 1.0, "ray_cm": 1.0, "rotation_deg": 20.0}
"""What each term alone must stay under for the (1 cm, 20°) match (translation in cm, rotation in degrees)."""


@dataclass
class ErrorTable:
    """One row per prediction: the ``TERMS`` errors, whether it matched at (1 cm, 20°), its shape, and its
    ``KEYPOINT_TERMS`` errors (NaN where the detector has no keypoints)."""

    rows: list[np.ndarray] = field(default_factory=list)
    matched: list[np.ndarray] = field(default_factory=list)
    shapes: list[np.ndarray] = field(default_factory=list)
    keypoints: list[np.ndarray] = field(default_factory=list)

    def add(self, errors: np.ndarray, matched: np.ndarray, shapes: np.ndarray,
            keypoints: np.ndarray | None = None) -> None:
        self.rows.append(errors)
        self.matched.append(matched)
        self.shapes.append(shapes)
        self.keypoints.append(np.full((len(errors), len(KEYPOINT_TERMS)), np.nan) if keypoints is None
                              else np.asarray(keypoints, dtype=float))

    def keypoint_arrays(self) -> np.ndarray:
        """(N, 4) the predictions' keypoint errors (px), NaN where none."""
        return np.concatenate(self.keypoints) if self.keypoints else np.zeros((0, len(KEYPOINT_TERMS)))

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self.rows:
            return np.zeros((0, len(TERMS))), np.zeros(0, dtype=bool), np.zeros(0, dtype="<U16")
        return np.concatenate(self.rows), np.concatenate(self.matched), np.concatenate(self.shapes)

    def summary(self) -> dict[str, Any]:
        """Per shape (and ``all``): predictions, 1 cm GSR, median / 90th percentile of each term, and the
        share of predictions (and of failures) each term alone would fail."""
        errors, matched, shapes = self.arrays()
        keypoints = self.keypoint_arrays()
        out: dict[str, Any] = {}
        for name in ("all", *SHAPES):
            sel = np.ones(len(errors), dtype=bool) if name == "all" else shapes == name
            if not sel.any():
                continue
            e, m = errors[sel], matched[sel]
            row: dict[str, Any] = {"predictions": int(sel.sum()), "gsr_1cm": float(m.mean())}
            for j, term in enumerate(TERMS):
                col = np.abs(e[:, j])
                row[term] = {"median": float(np.median(col)), "p90": float(np.percentile(col, 90))}
            kp = keypoints[sel]
            if np.isfinite(kp).all() and len(kp):
                for j, term in enumerate(KEYPOINT_TERMS):
                    row[term] = {"median": float(np.median(kp[:, j])), "p90": float(np.percentile(kp[:, j], 90))}
                mean = kp.mean(axis=1)
                row["keypoints_px"] = {"median": float(np.median(mean)), "p90": float(np.percentile(mean, 90))}
            for term, limit in _LIMITS.items():
                alone = np.abs(e[:, TERMS.index(term)]) >= limit
                row[term]["fails_alone"] = float(alone.mean())
                row[term]["share_of_failures"] = float(alone[~m].mean()) if (~m).any() else None
            out[name] = row
        return out


def grasp_errors(pred_world: np.ndarray, pred_widths: np.ndarray, grasps: GraspSet, obs: Observation
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The error rows (N, len(TERMS)) of predictions ``pred_world`` (N, 4, 4, world frame) against their nearest
    grasp of ``grasps`` (world frame, N ≥ 1 and M ≥ 1), their (1 cm, 20°) match against the free ones, and the
    index of each one's nearest grasp."""
    n = len(pred_world)
    _, d_r, nearest, matched = nearest_grasps(pred_world, grasps)
    cam_T_world = invert_pose(obs.camera_pose)
    p = transform_points(cam_T_world, pred_world[:, :3, 3])
    g = transform_points(cam_T_world, grasps.poses[nearest, :3, 3])
    K = obs.intrinsics.K
    px = np.linalg.norm(project(p, K) - project(g, K), axis=1)
    errors = np.stack([
        px,
        100.0 * px * g[:, 2] / K[0, 0],
        100.0 * (np.linalg.norm(p, axis=1) - np.linalg.norm(g, axis=1)),
        np.degrees(d_r[np.arange(n), nearest]),
        100.0 * (pred_widths - grasps.widths[nearest]),
    ], axis=1)
    return errors, matched, nearest


def keypoint_errors(pred_keypoints: np.ndarray, gt_world: np.ndarray, sides: np.ndarray, obs: Observation
                    ) -> np.ndarray:
    """(N, 4) pixel distances between predicted keypoints (N, 4, 2; L, R, TL, TR) and the projected box
    keypoints of grasps ``gt_world`` (N, 4, 4, world frame) with box sides ``sides`` (N,) m, each against the GT
    grasp's form (itself or its 180° flip) with the smaller mean distance (module docstring)."""
    T_cam_gt = invert_pose(obs.camera_pose) @ gt_world
    K = obs.intrinsics.K
    forms = []
    for poses in (T_cam_gt, flip_180(T_cam_gt)):
        pts = keypoints_in_frame(poses, sides)
        forms.append(np.linalg.norm(project(pts.reshape(-1, 3), K).reshape(-1, 4, 2) - pred_keypoints, axis=2))
    a, b = forms
    return np.where((a.mean(axis=1) <= b.mean(axis=1))[:, None], a, b)


def decompose_image(pred_world: np.ndarray, pred_widths: np.ndarray, gt: list[GraspSet], types: list[str],
                    obs: Observation, pred_keypoints: np.ndarray | None = None,
                    box_sides: Callable[[np.ndarray], np.ndarray] | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The error rows (N, len(TERMS)) of one image's predictions, their (1 cm, 20°) match against the free
    GT grasps, the shape each is attributed to, and their keypoint errors (N, 4) px against the nearest GT
    grasp (NaN unless ``pred_keypoints`` (N, 4, 2) and ``box_sides``, camera distances (m) → box sides (m),
    are given)."""
    grasps = GraspSet.concatenate(list(gt))
    if len(pred_world) == 0 or len(grasps) == 0:
        return (np.zeros((0, len(TERMS))), np.zeros(0, dtype=bool), np.zeros(0, dtype="<U16"),
                np.zeros((0, len(KEYPOINT_TERMS))))
    owner = np.repeat(np.arange(len(gt)), [len(g) for g in gt])
    errors, matched, nearest = grasp_errors(pred_world, pred_widths, grasps, obs)
    shapes = np.array([shape_column(types[i]) for i in owner[nearest]], dtype="<U16")
    keypoints = np.full((len(pred_world), len(KEYPOINT_TERMS)), np.nan)
    if pred_keypoints is not None and box_sides is not None:
        gt_world = grasps.poses[nearest]
        distance = np.linalg.norm(transform_points(invert_pose(obs.camera_pose), gt_world[:, :3, 3]), axis=1)
        keypoints = keypoint_errors(pred_keypoints, gt_world, box_sides(distance), obs)
    return errors, matched, shapes, keypoints


def decompose_dataset(detect: Callable[[Observation], Candidates], data_dir: Path, split: str = "test",
                      views: int | None = None, progress: bool = True) -> ErrorTable:
    """The ``ErrorTable`` of a detector over a split (the first ``views`` images); keypoint errors where the
    detector returns keypoints and has a ``variant`` (``detectors.kgn.KGNDetector``) whose box they belong to."""
    run = detector_call(detect)
    variant = getattr(detect, "variant", None)
    box_sides = variant.box_sides if variant is not None else None
    total, items = iter_views(data_dir, split, views)
    table = ErrorTable()
    bar = Progress(total, f"eval errors {split}", unit="images", enabled=progress)
    hits = predictions = 0
    for item in items:
        cands = run(item)
        errors, matched, shapes, keypoints = decompose_image(
            cands.world_poses(item.observation.camera_pose), cands.widths, item.gt, item.types, item.observation,
            cands.keypoints, box_sides)
        table.add(errors, matched, shapes, keypoints)
        hits, predictions = hits + int(matched.sum()), predictions + len(matched)
        bar.update(extra=f"GSR@1cm {100 * hits / max(predictions, 1):.0f}%")
    return table


def markdown(summary: dict[str, Any], title: str) -> str:
    """The table of ``ErrorTable.summary``: medians (90th percentiles) and the 1 cm failure shares."""
    lines = [f"# {title}", "",
             "Median (90th percentile) absolute error of each prediction against its nearest GT grasp; "
             "\"alone\" = share of predictions that term alone would fail at 1 cm / 20° (share of the actual "
             "failures in brackets).", "",
             "| shape | predictions | GSR 1 cm | centre px | centre cm | along ray cm | rotation ° | width cm | "
             "centre alone | ray alone | rotation alone |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]

    def share(x: dict) -> str:
        f = x.get("share_of_failures")
        return f"{100 * x['fails_alone']:.0f} % ({'n/a' if f is None else f'{100 * f:.0f} %'})"

    for name, row in summary.items():
        cells = [f"{row[t]['median']:.2f} ({row[t]['p90']:.2f})" for t in TERMS]
        lines.append(f"| {name} | {row['predictions']} | {100 * row['gsr_1cm']:.1f} % | " + " | ".join(cells)
                     + f" | {share(row['centre_cm'])} | {share(row['ray_cm'])} | {share(row['rotation_deg'])} |")
    rows = {name: row for name, row in summary.items() if "keypoints_px" in row}
    if rows:
        terms = (*KEYPOINT_TERMS, "keypoints_px")
        lines += ["", "Keypoint error before PnP (px in the 640 × 480 image), median (90th percentile), against "
                  "the nearest GT grasp's box keypoints:", "",
                  "| shape | " + " | ".join(KEYPOINT_NAMES) + " | mean of the 4 |", "|---|" + "---:|" * len(terms)]
        for name, row in rows.items():
            lines.append(f"| {name} | " + " | ".join(f"{row[t]['median']:.2f} ({row[t]['p90']:.2f})" for t in terms)
                         + " |")
    return "\n".join(lines) + "\n"


def cdf_figure(table: ErrorTable, title: str):
    """Cumulative distributions of the four terms, one line per shape."""
    from kgn_bench.viz.figures import Line, Panel, line_panels

    errors, _, shapes = table.arrays()
    panels = []
    for term, label, limit in (("centre_cm", "centre error in the image plane (cm)", 1.0),
                               ("ray_cm", "distance error along the ray (cm)", 1.0),
                               ("rotation_deg", "rotation error (°)", 20.0), ("width_cm", "width error (cm)", 1.0)):
        col = np.abs(errors[:, TERMS.index(term)])
        lines = []
        for k, name in enumerate(("all", *SHAPES)):
            v = np.sort(col if name == "all" else col[shapes == name])
            if len(v):
                lines.append(Line(name, v, np.arange(1, len(v) + 1) / len(v), color=k, dashed=name == "all",
                                  markers=False))
        lines.append(Line(f"1 cm / 20° limit ({limit:g})", [limit, limit], [0.0, 1.0], color=7, dashed=True,
                          markers=False))
        panels.append(Panel(label.split(" (")[0], label, "fraction of predictions", lines))
    fig = line_panels(panels, suptitle=title)
    for ax in fig.axes:
        ax.set_xscale("log")
    return fig


def write_errors(table: ErrorTable, out: Path, title: str, meta: dict[str, Any]) -> list[Path]:
    """``out``/errors.json, errors.md and errors.png."""
    from kgn_bench.viz.figures import save_figure

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary = table.summary()
    atomic_write_text(out / "errors.json", json.dumps({**meta, "summary": summary}, indent=1) + "\n")
    atomic_write_text(out / "errors.md", markdown(summary, title))
    save_figure(cdf_figure(table, title), out / "errors.png")
    return [out / "errors.json", out / "errors.md", out / "errors.png"]
