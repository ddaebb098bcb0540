"""How much of a detector's failure in GIGA's rounds the "dex" depth noise causes, term by term.

GIGA's noise (``sim.depth_noise.DexNoise``) has two terms: one multiplicative factor per image,
``α ~ Gamma(1000, 0.001)`` (standard deviation 3.2 %: at the 0.6 m of GIGA's camera the whole scene moves
about 1.9 cm along the camera rays), and, on half of the images, a smooth additive field of 5 mm. For each
trial of a run folder (task and seed from its ``run.json``), the first attempt is made again from the trial's
settled scene (``bench.scene_cache``) with the depth of the task camera under each variant, and executed:

* ``dex``: the noise as the task has it (the run's own first attempt, which this reproduces);
* ``no scale``: α = 1, the additive field as drawn;
* ``no field``: α as drawn, no additive field;
* ``clean``: the exact rendered depth.

Each variant draws from the same random stream as the run (``[seed, trial, 0]``), so they differ only in the
term switched off. Prints the first-attempt success of each variant, overall and by α, and writes
``<run>/explain/noise_study.json``.

    PYTHONPATH=results/calibration python results/calibration/noise_study.py RUN DETECTOR [N]
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import kgn_bench.bench.trial as trial
from kgn_bench.eval.explain import _open_run
from kgn_bench.sim import floating_hand
from kgn_bench.sim.control import IK
from kgn_bench.sim.depth_noise import DexNoise, _depth_image, upsample_bilinear
from kgn_bench.threads import trial_threads


@dataclass(frozen=True)
class Variant(DexNoise):
    """``DexNoise`` with either term switched off, drawing the same random numbers as the full model."""

    scale: bool = True
    field: bool = True

    def apply(self, depth: np.ndarray, fx: float, rng: np.random.Generator) -> np.ndarray:
        depth = _depth_image(depth)
        alpha = rng.gamma(self.gamma_shape, self.gamma_scale)
        out = depth * alpha if self.scale else depth.copy()
        if rng.random() < self.gp_probability:
            h, w = depth.shape
            noise = rng.normal(0.0, self.gp_sigma, (max(1, h // self.gp_downsample), max(1, w // self.gp_downsample)))
            if self.field:
                out = out + upsample_bilinear(noise, (h, w))
        return np.where(depth > 0, out, 0.0).astype(depth.dtype)


VARIANTS = {"dex": DexNoise(), "no scale": Variant(scale=False), "no field": Variant(field=False),
            "clean": Variant(scale=False, field=False)}


def first_grasp(r, index: int, ik: IK, noise: DexNoise) -> str | None:
    """The outcome of trial ``index``'s first grasp under ``noise`` (None: held; else the failure reason)."""
    trial.noise_model = lambda name, strength: noise
    cap = trial.capture(r.task, index, r.detector, ik, 1)
    if cap is None or cap.selection.grasp is None:
        return "no_candidate"
    return floating_hand.execute_grasp(cap.hand, cap.selection.grasp, allow_contact=True).reason


def main() -> None:
    run, detector = Path(sys.argv[1]), sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else None
    r = _open_run(run, detector)
    ik = IK()
    rows = []
    for index in sorted(r.records)[:n]:
        alpha = float(np.random.default_rng([r.task.seed, index, 0]).gamma(1000.0, 0.001))
        with trial_threads():
            outcome = {name: first_grasp(r, index, ik, v) for name, v in VARIANTS.items()}
        rows.append({"index": index, "alpha": alpha, "recorded": r.records[index].attempts[0].reason,
                     "outcome": outcome})
        print(index, f"{alpha:.3f}", " ".join(f"{k}:{'ok' if v is None else v}" for k, v in outcome.items()),
              flush=True)
    agree = sum(row["outcome"]["dex"] == row["recorded"] for row in rows)
    print(f"\n{len(rows)} first grasps ({agree} as recorded)\n")
    bands = ((0.0, 0.98), (0.98, 1.0), (1.0, 1.02), (1.02, 9.0))
    print("| variant | first grasps held | " + " | ".join(f"α in [{lo}, {hi})" for lo, hi in bands) + " |")
    print("|---|---:|" + "---:|" * len(bands))
    for name in VARIANTS:
        held = [row["outcome"][name] is None for row in rows]
        cells = []
        for lo, hi in bands:
            sub = [h for h, row in zip(held, rows, strict=True) if lo <= row["alpha"] < hi]
            cells.append(f"{sum(sub)}/{len(sub)}")
        print(f"| {name} | {sum(held)}/{len(held)} | " + " | ".join(cells) + " |")
    out = run / "explain" / "noise_study.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
