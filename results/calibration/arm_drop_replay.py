"""Why the arm drops grasps that the floating hand lifts (issue 42, "what the arm costs"): each lift drop of an
arm run, rebuilt at the state it happened in and executed again with one part of the arm's execution changed.

For every attempt of an arm run (``execution.hand = "arm"``) recorded as ``dropped_lift``, and for as many
recorded successes as controls, ``bench.trial.capture`` rebuilds the attempt once (the same settled scene, earlier
attempts executed as in the run, the same detector seed and selection). From that state each time (the
scene's snapshot restored, the arm's references reset), the
selected grasp ``T_world_grasp`` is executed by the arm as ``bench.attempt.execute_grasp`` does it (open to
the grasp's width plus the margin, joint move to the pre-grasp, straight approach, 0.2 s settle, jaws driven
shut over 0.4 s, 0.25 s wait, straight-up lift of ``lift_height`` in 0.8 s, ``settle_time``; the lift holds if
the same object is still between the pads and the point of it that was at the TCP rose ≥ ``min_lift``), and
with one change at a time:

* ``open fully``: the jaws open to the gripper's maximum before the approach (GIGA's hand);
* ``slow close``: jaws driven shut over 1.0 s and 0.75 s of wait before the lift;
* ``slow lift``: the lift takes 2.0 s instead of 0.8 s;
* ``lift along approach``: back out along −x of the grasp (the approach) instead of straight up, as GIGA's hand
  does for grasps within 60° of straight down (here for every grasp).

It prints, per variant, how many of the drops it turns into holds and how many of the controls it breaks,
and writes the outcomes to ``<run>/explain/arm_drop_replay.json``.

    python results/calibration/arm_drop_replay.py RUN [CONTROLS]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from kgn_bench.bench.attempt import held_object
from kgn_bench.bench.trial import capture
from kgn_bench.eval.explain import _open_run
from kgn_bench.gripper import GRIPPER
from kgn_bench.io import atomic_write_text
from kgn_bench.sim.control import IK, MotionAborted
from kgn_bench.sim.scene import PhysicsError
from kgn_bench.threads import trial_threads

VARIANTS = {
    "as run": {},
    "open fully": {"open_full": True},
    "slow close": {"close_time": 1.0, "close_wait": 0.75},
    "slow lift": {"lift_time": 2.0},
    "lift along approach": {"lift_along_approach": True},
}


def execute(cap, cfg, open_full=False, close_time=0.4, close_wait=0.25, lift_time=0.8,
            lift_along_approach=False) -> str:
    """The arm's attempt up to the lift check (``bench.attempt.execute_grasp``), with the given changes;
    returns ``held``, ``dropped_lift``, ``missed`` or the aborting reason."""
    scene, ex, sel = cap.scene, cap.hand, cap.selection
    try:
        ex.set_gripper(GRIPPER.max_width if open_full else sel.width, 0.2)
        ex.move_joints(sel.q_pregrasp)
        ex.move_linear(sel.grasp, cfg.approach_time)
        ex.wait(0.2)
    except MotionAborted as e:
        return f"aborted ({e.reason})"
    except PhysicsError:
        return "physics_error"
    try:
        ex.set_gripper(0.0, close_time)
        ex.wait(close_wait)
        held = held_object(scene, ex)
        if held is None:
            return "missed"
        T0 = scene.object_pose(held)
        grip = np.linalg.solve(T0, np.append(scene.data.site_xpos[ex.robot.tcp_site], 1.0))
        lift = ex.ik.tcp_pose(ex.q_ref)
        if lift_along_approach:
            lift[:3, 3] -= cfg.lift_height * sel.grasp[:3, 0]
        else:
            lift[2, 3] += cfg.lift_height
        ex.move_linear(lift, lift_time)
        ex.wait(cfg.settle_time)
        rise = float((scene.object_pose(held) @ grip)[2] - (T0 @ grip)[2])
        needed = cfg.min_lift * (abs(sel.grasp[2, 0]) if lift_along_approach else 1.0)
        return "held" if held_object(scene, ex) == held and rise >= needed else "dropped_lift"
    except (MotionAborted, PhysicsError) as e:
        return f"aborted ({type(e).__name__})"


def main() -> None:
    run = Path(sys.argv[1])
    controls = int(sys.argv[2]) if len(sys.argv) > 2 else 20
    r = _open_run(run)
    cfg = r.task.execution
    drops = [(i, k + 1) for i in sorted(r.records) for k, a in enumerate(r.records[i].attempts)
             if a.reason == "dropped_lift"]
    wins = [(i, k + 1) for i in sorted(r.records) for k, a in enumerate(r.records[i].attempts) if a.reason is None]
    rng = np.random.default_rng(0)
    picked = [wins[j] for j in sorted(rng.choice(len(wins), size=min(controls, len(wins)), replace=False))]
    ik = IK()
    rows = []
    for kind, cases in (("drop", drops), ("control", picked)):
        for index, attempt in cases:
            with trial_threads():
                cap = capture(r.task, index, r.detector, ik, attempt)
                if cap is None or cap.selection.grasp is None:
                    continue
                start, q0, g0 = cap.scene.snapshot(), cap.hand.q_ref.copy(), cap.hand.grip_ref
                outcome = {}
                for name, change in VARIANTS.items():
                    cap.scene.restore(start)
                    cap.hand.q_ref, cap.hand.grip_ref = q0.copy(), g0
                    outcome[name] = execute(cap, cfg, **change)
            rows.append({"kind": kind, "trial": index, "attempt": attempt, "outcome": outcome})
            print(kind, index, attempt, outcome, flush=True)
    print(f"\n| variant | drops it turns into holds (of {len(drops)}) | controls it breaks (of {len(picked)}) |")
    print("|---|---:|---:|")
    for name in VARIANTS:
        fixed = sum(row["outcome"][name] == "held" for row in rows if row["kind"] == "drop")
        broken = sum(row["outcome"][name] != "held" for row in rows if row["kind"] == "control")
        print(f"| {name} | {fixed} | {broken} |")
    unfixed = sum(not any(v == "held" for k, v in row["outcome"].items() if k != "as run")
                  for row in rows if row["kind"] == "drop")
    print(f"\n{unfixed} of {len(drops)} drops are fixed by none of the changes.")
    out = run / "explain" / "arm_drop_replay.json"
    out.parent.mkdir(exist_ok=True)
    atomic_write_text(out, json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
