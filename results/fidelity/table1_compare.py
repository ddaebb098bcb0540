"""Table I old beside new beside the paper (issue 43, item 5): two ``vision_table1.json`` files written by
``kgn-bench experiment table1``, each row of the table as ``old → new (paper)``.

    python results/fidelity/table1_compare.py OLD_JSON NEW_JSON [--old-label L] [--new-label L]
    python results/fidelity/table1_compare.py git:REV NEW_JSON     # the table committed at REV

``git:REV`` reads ``results/vision_table1.json`` as committed at revision REV (e.g. the commit before the
recipe-4 weights were shipped), so the old table needs no copy of its own.
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path

ROWS = ("kgn_single", "kgn_multi", "kgnv2_single", "kgnv2_multi")
LABELS = {"kgn_single": "KGN (single)", "kgn_multi": "KGN (multi)", "kgnv2_single": "KGNv2 (single)",
          "kgnv2_multi": "KGNv2 (multi)"}


def load(source: str) -> dict:
    """A Table I JSON from a path or from ``git:REV`` (``results/vision_table1.json`` at REV)."""
    if source.startswith("git:"):
        text = subprocess.run(["git", "show", f"{source[4:]}:results/vision_table1.json"], check=True,
                              capture_output=True, text=True).stdout
        return json.loads(text)
    return json.loads(Path(source).read_text())


def _triple(values: list[float] | None) -> str:
    return "—" if values is None else " / ".join(f"{v:.1f}" for v in values)


def table(old: dict, new: dict, old_label: str = "old", new_label: str = "new") -> str:
    """Markdown: per test split, per model, one row each for old, new, the paper and new − old."""
    thresholds = new["thresholds"]
    lines = []
    for test in ("single", "multi"):
        lines += [f"## {test.capitalize()}-object test split (GSR / GCR / OSR %)", "",
                  "| model | | " + " | ".join(thresholds) + " |", "|---|---|" + "---:|" * len(thresholds)]
        for name in ROWS:
            o = old["ours"].get(name, {}).get(test)
            n = new["ours"].get(name, {}).get(test)
            p = new["paper"][name][test]
            lines.append(f"| {LABELS[name]} | {old_label} | " + " | ".join(
                _triple(o[k] if o else None) for k in range(len(thresholds))) + " |")
            lines.append(f"| | {new_label} | " + " | ".join(
                _triple(n[k] if n else None) for k in range(len(thresholds))) + " |")
            lines.append("| | paper | " + " | ".join(_triple(p[k]) for k in range(len(thresholds))) + " |")
            delta = [" / ".join(f"{b - a:+.1f}" for a, b in zip(o[k], n[k])) if o and n else "—"
                     for k in range(len(thresholds))]
            lines.append(f"| | {new_label} − {old_label} | " + " | ".join(delta) + " |")
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", help="a vision_table1.json, or git:REV")
    parser.add_argument("new", help="a vision_table1.json, or git:REV")
    parser.add_argument("--old-label", default="old")
    parser.add_argument("--new-label", default="new")
    args = parser.parse_args()
    print(table(load(args.old), load(args.new), args.old_label, args.new_label))


if __name__ == "__main__":
    main()
