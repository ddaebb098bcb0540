"""Compare the records of two runs of the same task: every trials.jsonl line (less its wall-clock ``timing``)
and summary.json / summary.md byte for byte. Prints one line per file and exits 1 on any difference.

    .venv/bin/python results/architecture/compare_runs.py RUN_A RUN_B
"""

import hashlib
import json
import sys
from pathlib import Path


def _trials(run: Path) -> list[str]:
    lines = []
    for line in (run / "trials.jsonl").read_text().splitlines():
        record = json.loads(line)
        record.pop("timing", None)
        lines.append(json.dumps(record, sort_keys=False))
    return sorted(lines, key=lambda s: json.loads(s)["index"])


def main(a: Path, b: Path) -> int:
    same = True
    ta, tb = _trials(a), _trials(b)
    changed = sum(x != y for x, y in zip(ta, tb)) + abs(len(ta) - len(tb))
    print(f"trials.jsonl  {len(ta)} / {len(tb)} trials, {changed} differ (timing excluded)")
    same &= changed == 0
    for name in ("summary.json", "summary.md"):
        da, db = (hashlib.sha256((r / name).read_bytes()).hexdigest()[:12] for r in (a, b))
        print(f"{name:<13} {'identical' if da == db else 'DIFFERENT'} ({da} / {db})")
        same &= da == db
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1]), Path(sys.argv[2])))
