"""What would have made VGN's first grasps of GIGA's rounds hold: the same grasp moved along its approach, or
turned about it, executed again in physics from the same settled scene.

For trial i of a run folder (seed and task from its ``run.json``), the first attempt is re-created as the run
made it (``bench.trial``: the cached settled scene, the task camera and noise, the detector, the selector);
then, from that state each time, the floating hand executes the selected grasp ``T`` (world; +x approach, z
closing) as selected, and its variants:

* **depth d**: ``T`` with its origin moved ``d`` along its approach, ``t + d · x`` (d > 0: deeper, towards the
  palm's stop; d < 0: further out);
* **yaw a**: ``T · R_x(a)``, the jaws turned by ``a`` about the approach through the same centre
  (a = 180° is the same grasp for a symmetric gripper, so 45°, 90° and 135° cover it).

It prints how many of the as-selected failures each variant turns into a success, and how many successes it
breaks, and writes the per-trial outcomes to ``<run>/explain/counterfactual.json``.

    PYTHONPATH=results/calibration python results/calibration/vgn_counterfactual.py RUN DETECTOR [N]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from kgn_bench.bench.trial import capture
from kgn_bench.eval.explain import _open_run
from kgn_bench.geometry import make_pose, rot_x
from kgn_bench.sim import floating_hand
from kgn_bench.sim.control import IK
from kgn_bench.threads import trial_threads

DEPTHS_CM = (-1.0, 1.0, 2.0, 3.0)
YAWS_DEG = (45.0, 90.0, 135.0)


def variants(T: np.ndarray) -> dict[str, np.ndarray]:
    """The selected grasp and its depth and yaw variants (module doc), by name."""
    out = {"as selected": T}
    for d in DEPTHS_CM:
        V = T.copy()
        V[:3, 3] += d / 100.0 * T[:3, 0]
        out[f"depth {d:+.0f} cm"] = V
    for a in YAWS_DEG:
        out[f"yaw {a:.0f}°"] = T @ make_pose(rot_x(np.deg2rad(a)))
    return out


def main() -> None:
    run, detector = Path(sys.argv[1]), sys.argv[2]
    n = int(sys.argv[3]) if len(sys.argv) > 3 else None
    r = _open_run(run, detector)
    ik = IK()
    rows = []
    for index in sorted(r.records)[:n]:
        with trial_threads():
            outcome = _variants_outcomes(r, index, ik)
        if outcome is None:
            continue
        recorded = r.records[index].attempts[0]
        rows.append({"index": index, "recorded": recorded.reason, "outcome": outcome})
        print(index, "ok" if outcome["as selected"] is None else outcome["as selected"],
              " ".join(k for k, v in outcome.items() if v is None), flush=True)
    _report(run, rows)


def _variants_outcomes(r, index: int, ik: IK) -> dict[str, str | None] | None:
    """Each variant's outcome (None: held; else the failure reason) for trial ``index``'s first grasp; None
    when nothing was selected."""
    cap = capture(r.task, index, r.detector, ik, 1)
    if cap is None or cap.selection.grasp is None:
        return None
    scene, hand = cap.scene, cap.hand
    start = scene.snapshot()
    outcome: dict[str, str | None] = {}
    for name, T in variants(cap.selection.grasp).items():
        scene.restore(start)
        outcome[name] = floating_hand.execute_grasp(hand, T, allow_contact=True).reason
    return outcome


def _report(run: Path, rows: list[dict]) -> None:
    failed = [row for row in rows if row["outcome"]["as selected"] is not None]
    held = [row for row in rows if row["outcome"]["as selected"] is None]
    agree = sum((row["outcome"]["as selected"] or None) == row["recorded"] for row in rows)
    print(f"\n{len(rows)} first grasps re-executed ({agree} with the recorded outcome); {len(held)} held, "
          f"{len(failed)} failed")
    print("| variant | failures it turns into holds | holds it breaks |\n|---|---:|---:|")
    for name in variants(np.eye(4)):
        if name == "as selected":
            continue
        fixed = sum(row["outcome"][name] is None for row in failed)
        broken = sum(row["outcome"][name] is not None for row in held)
        print(f"| {name} | {fixed}/{len(failed)} | {broken}/{len(held)} |")
    any_depth = sum(any(row["outcome"][f"depth {d:+.0f} cm"] is None for d in DEPTHS_CM) for row in failed)
    any_yaw = sum(any(row["outcome"][f"yaw {a:.0f}°"] is None for a in YAWS_DEG) for row in failed)
    print(f"| any depth | {any_depth}/{len(failed)} | |\n| any yaw | {any_yaw}/{len(failed)} | |")
    out = run / "explain" / "counterfactual.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
