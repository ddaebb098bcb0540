"""The arm-versus-floating-hand table (issue 42, item 4) from the runs of ``arm_vs_floating.sh``.

    .venv/bin/python results/calibration/arm_vs_floating_table.py [RUNS] > results/calibration/arm_vs_floating.md

``RUNS`` (default ``runs/arm_vs_floating``) holds ``<task>/<hand>/<detector>/summary.json`` with hand
``floating`` or ``arm``: the same rounds (task, seed, objects, placement, camera, noise) executed both ways.
Per task and detector: GSR and DR (GIGA's success and declutter rates, ``bench.stats``) with Wilson 95 %
intervals, and the failure reasons of each execution; the reasons the floating hand cannot have (``ARM_ONLY``:
reach and IK, the carry to the bin) are listed apart. A detector run only one way is shown
with a dash on the other side.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HANDS = ("floating", "arm")
ARM_ONLY = ("unreachable", "dropped_transport")
"""Failure reasons that only an execution by the arm can give (``bench.attempt.FAILURE_REASONS``): no IK
solution (or none clear of the arm's links), and a drop on the carry to the bin; the floating hand reaches
every pose and lifts in place. A collision can happen to both."""


def _rate(summary: dict | None, key: str) -> str:
    if summary is None:
        return "–"
    r = summary["rates"][key]
    return f"{100 * r['rate']:.1f} [{100 * r['low']:.1f}, {100 * r['high']:.1f}] ({r['k']}/{r['n']})"


def _reasons(summary: dict | None, keep) -> str:
    if summary is None:
        return "–"
    items = [f"{k} {v}" for k, v in summary["failures"].items() if v and keep(k)]
    return ", ".join(items) or "none"


def table(runs: Path) -> str:
    lines = ["# What the arm costs: the same rounds, executed by the floating hand and by the arm", "",
             f"From `{runs}` (`results/calibration/arm_vs_floating.sh`). GSR: grasps that held over grasps tried; "
             "DR: objects removed over objects in play; Wilson 95 % intervals.", ""]
    for task_dir in sorted(p for p in runs.iterdir() if p.is_dir()):
        detectors = sorted({d.name for hand in HANDS for d in (task_dir / hand).glob("*/") if d.is_dir()})
        if not detectors:
            continue
        lines += [f"## {task_dir.name}", "",
                  "| detector | floating GSR | floating DR | arm GSR | arm DR | failures, floating | failures, arm "
                  "(both) | failures only the arm has |",
                  "|---|---|---|---|---|---|---|---|"]
        for det in detectors:
            s = {}
            for hand in HANDS:
                path = task_dir / hand / det / "summary.json"
                s[hand] = json.loads(path.read_text()) if path.is_file() else None
            lines.append(f"| `{det}` | {_rate(s['floating'], 'success')} | {_rate(s['floating'], 'clear')} "
                         f"| {_rate(s['arm'], 'success')} | {_rate(s['arm'], 'clear')} "
                         f"| {_reasons(s['floating'], lambda k: True)} "
                         f"| {_reasons(s['arm'], lambda k: k not in ARM_ONLY)} "
                         f"| {_reasons(s['arm'], lambda k: k in ARM_ONLY)} |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(table(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("runs/arm_vs_floating")))
