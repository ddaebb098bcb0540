"""Training runs side by side, epoch by epoch, from their ``history.jsonl`` (issue 43's experiments).

    .venv/bin/python results/fidelity/compare_histories.py LABEL=HISTORY [LABEL=HISTORY ...] [--threshold "1 cm / 20°"]

Prints a markdown table: per epoch, each run's total loss and, on the epochs it was evaluated, its held-out
GSR / GCR / OSR (%) at the threshold (default all three, one column group each), and its seconds per epoch.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def _rows(path: Path) -> dict[int, dict]:
    return {row["epoch"]: row for row in map(json.loads, path.read_text().splitlines()) if row}


def table(runs: dict[str, Path], thresholds: list[str] | None = None) -> str:
    histories = {label: _rows(path) for label, path in runs.items()}
    epochs = sorted({e for h in histories.values() for e in h})
    if thresholds is None:
        thresholds = next((list(r["eval"]) for h in histories.values() for r in h.values() if "eval" in r), [])
    head = ["epoch"] + [f"{label} loss" for label in histories]
    head += [f"{label}, {t}" for t in thresholds for label in histories]
    head += [f"{label} s" for label in histories]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for e in epochs:
        cells = [str(e)]
        cells += [f"{h[e]['total']:.4f}" if e in h else "" for h in histories.values()]
        for t in thresholds:
            for h in histories.values():
                ev = h.get(e, {}).get("eval", {}).get(t)
                cells.append(f"{100 * ev['gsr']:.1f} / {100 * ev['gcr']:.1f} / {100 * ev['osr']:.1f}" if ev else "")
        cells += [f"{h[e]['seconds']:.0f}" if e in h else "" for h in histories.values()]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", metavar="LABEL=HISTORY")
    parser.add_argument("--threshold", action="append", help="a held-out threshold's label (default: all)")
    args = parser.parse_args()
    runs = dict(item.split("=", 1) for item in args.runs)
    print(table({label: Path(path) for label, path in runs.items()}, args.threshold))


if __name__ == "__main__":
    main()
