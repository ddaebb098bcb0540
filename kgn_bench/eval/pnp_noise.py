"""The paper's Fig. 2 study: how keypoint noise turns into pose error as the grasp moves away from the camera.

Set-up (KGNv2 §III-B): a grasp with a uniformly random orientation ``R`` sits at the origin of its frame; the
camera looks at it along its optical axis from distance ``d``, so in the OpenCV camera frame
``T_cam_grasp = [R | (0, 0, d)]``. The box keypoints (L, R, TL, TR) of side ``a`` are projected with the
RealSense intrinsics, each pixel coordinate gets independent Gaussian noise N(0, σ²), and IPPE
(``solve_box_pnp_batch``) recovers the pose from the noisy points. Two boxes are compared:

* ``fixed``: a = ``BOX_SIDE`` (KGN); the recovered translation is the metric PnP translation;
* ``scale_normalized``: a = k · d · ``BOX_SIDE`` (KGNv2's scale-normalised keypoints, k the ``kgnv2`` variant's
  ``box_coeff``); the PnP translation keeps its direction and its length is set to the true scale d, as the
  detector does with its predicted ŝ.

Errors per sample: rotation ``grasp_rotation_error`` (geodesic, 180° symmetric, the vision metric's rule) in
degrees and translation ‖t̂ − t‖ in centimetres. The same orientations and noise draws (in units of σ) are
used at every distance, σ and box, so the curves differ only by the quantity on the axis. Samples where
IPPE fails or puts the grasp behind the camera are counted in ``failures`` and left out of the statistics.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from kgn_bench.camera import REALSENSE
from kgn_bench.errors import InputError
from kgn_bench.grasp import grasp_rotation_error, keypoints_in_frame
from kgn_bench.io import atomic_write_text
from kgn_bench.model.decode import solve_box_pnp_batch
from kgn_bench.model.variants import BOX_SIDE, get_variant

__all__ = ["BOXES", "PnpNoiseConfig", "PnpNoiseRow", "plot_pnp_noise", "random_rotations", "rows_to_csv",
           "run_pnp_noise", "write_pnp_noise"]

BOXES = ("fixed", "scale_normalized")


@dataclass(frozen=True)
class PnpNoiseConfig:
    """Camera distances d (m), keypoint noise levels σ (px), orientations per (d, σ, box) and the seed."""

    distances: tuple[float, ...] = tuple(round(0.3 + 0.1 * i, 2) for i in range(13))
    sigmas: tuple[float, ...] = (1.0, 2.0, 4.0)
    samples: int = 2000
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.distances or not all(d > 0.0 and math.isfinite(d) for d in self.distances):
            raise InputError(f"distances must be positive, got {self.distances}")
        if not self.sigmas or not all(s >= 0.0 and math.isfinite(s) for s in self.sigmas):
            raise InputError(f"noise levels must be non-negative, got {self.sigmas}")
        if int(self.samples) != self.samples or self.samples < 1:
            raise InputError(f"samples must be a positive integer, got {self.samples}")


@dataclass(frozen=True)
class PnpNoiseRow:
    """Error statistics of one (box, σ, d) cell: rotation in degrees, translation in centimetres."""

    box: str
    sigma_px: float
    distance_m: float
    rot_mean_deg: float
    rot_median_deg: float
    trans_mean_cm: float
    trans_median_cm: float
    samples: int
    failures: int


def random_rotations(n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` rotation matrices (n, 3, 3) uniformly distributed on SO(3): normalised Gaussian quaternions
    (w, x, y, z), drawn from ``rng`` (scipy's ``Rotation``)."""
    return Rotation.from_quat(rng.standard_normal((n, 4)), scalar_first=True).as_matrix()


def _box_side(box: str, distance: float) -> float:
    if box == "fixed":
        return BOX_SIDE
    if box == "scale_normalized":
        return float(get_variant("kgnv2").box_sides(np.array([distance]))[0])
    raise ValueError(f"unknown box {box!r} (known: {', '.join(BOXES)})")


def run_pnp_noise(config: PnpNoiseConfig = PnpNoiseConfig()) -> list[PnpNoiseRow]:
    """The study's table: one row per (box, σ, d), boxes outermost, distances innermost."""
    rng = np.random.default_rng(config.seed)
    K = REALSENSE.K
    n = config.samples
    rotations = random_rotations(n, rng)
    unit_noise = rng.standard_normal((n, 4, 2))
    rows: list[PnpNoiseRow] = []
    for box in BOXES:
        for sigma in config.sigmas:
            for d in config.distances:
                truth = np.repeat(np.eye(4)[None], n, axis=0)
                truth[:, :3, :3] = rotations
                truth[:, 2, 3] = d
                side = _box_side(box, d)
                cam = keypoints_in_frame(truth, side)
                pixels = (cam @ K.T)[..., :2] / cam[..., 2:3] + sigma * unit_noise
                poses, _, ok = solve_box_pnp_batch(pixels, K, side)
                t = poses[ok, :3, 3]
                if box == "scale_normalized":
                    t = d * t / np.linalg.norm(t, axis=1, keepdims=True)
                rot = np.degrees(grasp_rotation_error(poses[ok, :3, :3], rotations[ok]))
                trans = 100.0 * np.linalg.norm(t - truth[ok, :3, 3], axis=1)
                nan = float("nan")
                rows.append(
                    PnpNoiseRow(
                        box=box,
                        sigma_px=float(sigma),
                        distance_m=float(d),
                        rot_mean_deg=float(rot.mean()) if len(rot) else nan,
                        rot_median_deg=float(np.median(rot)) if len(rot) else nan,
                        trans_mean_cm=float(trans.mean()) if len(trans) else nan,
                        trans_median_cm=float(np.median(trans)) if len(trans) else nan,
                        samples=int(ok.sum()),
                        failures=int((~ok).sum()),
                    )
                )
    return rows


_FIELDS = ("box", "sigma_px", "distance_m", "rot_mean_deg", "rot_median_deg", "trans_mean_cm", "trans_median_cm",
           "samples", "failures")


def rows_to_csv(rows: list[PnpNoiseRow]) -> str:
    """The rows as CSV text with a header line; floats with 4 significant decimals."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(_FIELDS)
    for r in rows:
        values = [getattr(r, f) for f in _FIELDS]
        writer.writerow([f"{v:.4f}" if isinstance(v, float) else v for v in values])
    return buf.getvalue()


def plot_pnp_noise(rows: list[PnpNoiseRow], statistic: str = "mean"):
    """Fig. 2 as a matplotlib figure: rotation (left) and translation (right) error against camera distance,
    one colour per σ, solid for the fixed box and dashed for the scale-normalised one, log scale;
    ``statistic`` is ``mean`` (the paper's) or ``median``."""
    from kgn_bench.viz.figures import Line, Panel, line_panels

    if statistic not in ("mean", "median"):
        raise ValueError(f"statistic must be mean or median, got {statistic!r}")
    sigmas = sorted({r.sigma_px for r in rows})
    panels = []
    for quantity, unit, ylabel in (("rot", "deg", "rotation error (°)"), ("trans", "cm", "translation error (cm)")):
        lines = []
        for i, sigma in enumerate(sigmas):
            for box in BOXES:
                cell = sorted((r for r in rows if r.box == box and r.sigma_px == sigma), key=lambda r: r.distance_m)
                name = "fixed 0.1 m box" if box == "fixed" else "scale-normalised box"
                lines.append(Line(f"{name}, σ = {sigma:g} px", [r.distance_m for r in cell],
                                  [getattr(r, f"{quantity}_{statistic}_{unit}") for r in cell], color=i,
                                  dashed=box != "fixed"))
        panels.append(Panel(f"{statistic} {ylabel.split(' (')[0]} vs distance (IPPE)", "camera distance (m)", ylabel,
                            lines, log_y=True))
    return line_panels(panels)


def write_pnp_noise(rows: list[PnpNoiseRow], out: Path) -> list[Path]:
    """Write ``out``.csv (all rows) and ``out``.png (the mean-error figure); returns the paths."""
    from kgn_bench.viz.figures import save_figure

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    csv_path, png_path = out.with_suffix(".csv"), out.with_suffix(".png")
    atomic_write_text(csv_path, rows_to_csv(rows))
    save_figure(plot_pnp_noise(rows), png_path)
    return [csv_path, png_path]
