"""Detectors in GIGA's rounds on the thin test objects and on the others (issue 42: the packed DR gap).

An object is *thin* when the smallest extent of its oriented bounding box, once sized as GIGA sizes it
(``shapes.scaled.giga_sized`` with the round's U(0.8, 1.0) or U(0.7, 0.9) factor left out), is under 3.5 cm:
pybullet's procedural plates and sticks. For each detector of a benchmark's runs folder
(``RUNS/<task>/<detector>/seed<k>``) it prints the objects removed over the objects placed, for thin objects
and for the others, and how many of the rounds that ended with no candidate had only thin objects left.

    python results/calibration/thin_objects.py runs/giga5
"""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path

from kgn_bench.shapes.library import load_object
from kgn_bench.shapes.scaled import giga_sized, oriented_extents

THIN_CM = 3.5


def smallest_extent_cm(name: str) -> float:
    """The object's smallest oriented extent (cm) at GIGA's size, before the round's random factor."""
    return 100.0 * float(oriented_extents(giga_sized(load_object(name), 1.0))[2])


def _rate(count: Counter[str], kind: str) -> str:
    k, n = count[f"{kind}_removed"], count[f"{kind}_placed"]
    return f"{100 * k / max(n, 1):.1f} % ({k}/{n})"


def main() -> None:
    runs = Path(sys.argv[1])
    thin: dict[str, bool] = {}
    for task in sorted(p for p in runs.iterdir() if p.is_dir()):
        print(f"## {task.name}\n")
        print("| detector | thin: removed / placed | others: removed / placed | rounds ended with no candidate | "
              "of them, only thin objects left |")
        print("|---|---|---|---:|---:|")
        for det in sorted(p for p in task.iterdir() if p.is_dir()):
            count: Counter[str] = Counter()
            for trials in sorted(det.glob("seed*/trials.jsonl")):
                for line in trials.read_text().splitlines():
                    rec = json.loads(line)
                    for name in rec["placed_objects"]:
                        if name not in thin:
                            thin[name] = smallest_extent_cm(name) < THIN_CM
                    # as the report counts: objects of a type put in the bin / placed (a round may draw a type twice)
                    placed = Counter(rec["placed_objects"])
                    removed = Counter(a["object"] for a in rec["attempts"] if a["success"])
                    for name, n in placed.items():
                        count[f"{'thin' if thin[name] else 'other'}_placed"] += n
                    for name, n in removed.items():
                        count[f"{'thin' if thin[name] else 'other'}_removed"] += n
                    if rec["attempts"] and rec["attempts"][-1]["reason"] == "no_candidate":
                        count["no_candidate"] += 1
                        left = list(placed - removed)
                        count["only_thin_left"] += bool(left) and all(thin[name] for name in left)
            print(f"| {det.name} | {_rate(count, 'thin')} | {_rate(count, 'other')} | {count['no_candidate']} | "
                  f"{count['only_thin_left']} |")
        print()
    print(f"thin objects (smallest extent < {THIN_CM} cm at GIGA's size): "
          + ", ".join(sorted(n for n, t in thin.items() if t)))


if __name__ == "__main__":
    main()
