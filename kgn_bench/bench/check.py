"""Regression check of a run against a stored baseline.

The test, per rate (success, and clear for clearance runs): a **regression** is declared when the run's
Wilson 95 % interval lies entirely below the baseline's, i.e. ``run.high < baseline.low``. Disjoint 95 %
intervals correspond to a difference significant at well below the 5 % level, so random variation of a
detector that did not change almost never fails the check, while a real drop of more than the combined
interval half-widths does. Rates that rose or overlap pass.

A baseline file holds one baseline per detector: ``{"baselines": {detector: {identity..., "rates": {...}}}}``
with each rate as ``{"k", "n", ...}``; a run is compared with the entry of its own detector. (A file holding a
single baseline at the top level is read too.)
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kgn_bench.data.format import atomic_write_text

from .stats import Rate

__all__ = ["CheckRow", "baseline_for", "baseline_from_summary", "compare", "format_check", "write_baseline"]

IDENTITY = ("task", "protocol", "detector", "seed", "trials")


@dataclass(frozen=True)
class CheckRow:
    name: str
    baseline: Rate
    run: Rate

    @property
    def regressed(self) -> bool:
        return self.run.interval[1] < self.baseline.interval[0]


def compare(summary: dict[str, Any], baseline: dict[str, Any]) -> list[CheckRow]:
    """One row per rate present in both; a ``ValueError`` if they share none."""
    rows = [CheckRow(name, Rate.from_dict(b), Rate.from_dict(summary["rates"][name]))
            for name, b in baseline["rates"].items() if name in summary["rates"]]
    if not rows:
        raise ValueError("the run and the baseline share no rate to compare")
    return rows


def format_check(rows: list[CheckRow], summary: dict[str, Any], baseline: dict[str, Any]) -> str:
    lines = [f"{'rate':<16} {'baseline':<32} {'run':<32} verdict"]
    for r in rows:
        lines.append(f"{r.name:<16} {r.baseline!s:<32} {r.run!s:<32} {'REGRESSION' if r.regressed else 'ok'}")
    differ = [k for k in IDENTITY if k in baseline and summary.get(k) != baseline.get(k)]
    if differ:
        lines.append("note: run and baseline differ in " + ", ".join(f"{k} ({summary.get(k)} vs {baseline.get(k)})"
                                                               for k in differ))
    return "\n".join(lines)


def baseline_from_summary(summary: dict[str, Any]) -> dict[str, Any]:
    return {**{k: summary[k] for k in IDENTITY if k in summary}, "rates": summary["rates"]}


def baseline_for(document: dict[str, Any], detector: str) -> dict[str, Any]:
    """The baseline of ``detector`` in a baseline file's contents; ``ValueError`` naming those it has."""
    if "baselines" not in document:
        return document
    try:
        return document["baselines"][detector]
    except KeyError:
        have = ", ".join(sorted(document["baselines"])) or "none"
        raise ValueError(f"no baseline for detector {detector!r} (it has: {have})") from None


def write_baseline(summary: dict[str, Any], path: Path) -> None:
    """Set the baseline of the run's detector in ``path`` (created if missing), keeping the other detectors'."""
    path = Path(path)
    document: dict[str, Any] = {"baselines": {}}
    if path.is_file():
        old = json.loads(path.read_text())
        if "baselines" in old:
            document = old
    document["baselines"][summary["detector"]] = baseline_from_summary(summary)
    document["baselines"] = dict(sorted(document["baselines"].items()))
    atomic_write_text(path, json.dumps(document, indent=2) + "\n")
