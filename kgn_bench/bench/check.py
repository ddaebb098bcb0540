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

from kgn_bench.errors import KGNBenchError
from kgn_bench.io import atomic_write_text

from .stats import Rate

__all__ = ["CheckError", "CheckRow", "baseline_for", "baseline_from_summary", "compare", "format_check",
           "read_baseline", "read_summary", "validate_baseline", "write_baseline"]


class CheckError(KGNBenchError, ValueError):
    """A run summary or a baseline file that cannot be used (missing, not JSON, of the wrong shape)."""


def _read_json(path: Path, what: str) -> Any:
    if not path.is_file():
        raise CheckError(f"{what} {path} not found")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise CheckError(f"{what} {path} is not valid JSON ({e})") from None
    except UnicodeDecodeError:
        raise CheckError(f"{what} {path} is not UTF-8 text") from None


def _validate_rates(rates: Any, where: str) -> None:
    if not isinstance(rates, dict) or not rates:
        raise CheckError(f"{where}: 'rates' must be a non-empty table of rates")
    for name, r in rates.items():
        ok = (isinstance(r, dict) and all(isinstance(r.get(k), int) and not isinstance(r.get(k), bool)
                                          for k in ("k", "n")) and 0 <= r["k"] <= r["n"])
        if not ok:
            raise CheckError(f"{where}: rate {name!r} must have integers k and n with 0 ≤ k ≤ n, got {r!r}")


def read_summary(run: Path) -> dict[str, Any]:
    """A run folder's ``summary.json``, checked to have a detector and rates; ``CheckError`` otherwise."""
    path = Path(run) / "summary.json"
    if not path.is_file():
        raise CheckError(f"{path} not found: run the benchmark first")
    summary = _read_json(path, "run summary")
    if not isinstance(summary, dict) or not isinstance(summary.get("detector"), str):
        raise CheckError(f"{path} is not a run summary (no detector)")
    _validate_rates(summary.get("rates"), str(path))
    return summary


def validate_baseline(document: Any, path: Path | str) -> dict[str, Any]:
    """``document`` if it is a baseline file's contents: ``{"baselines": {detector: baseline}}`` or a single
    baseline, each baseline a table with ``rates`` (``{name: {"k": int, "n": int}}``); ``CheckError`` naming
    what is wrong otherwise."""
    if not isinstance(document, dict):
        raise CheckError(f"baseline {path}: expected a JSON object, got {type(document).__name__}")
    entries = document.get("baselines", None)
    if entries is None:
        entries = {"(top level)": document}
    elif not isinstance(entries, dict):
        raise CheckError(f"baseline {path}: 'baselines' must be a table of detectors")
    for detector, entry in entries.items():
        if not isinstance(entry, dict):
            raise CheckError(f"baseline {path}: the entry of {detector!r} must be a table")
        _validate_rates(entry.get("rates"), f"baseline {path} [{detector}]")
    return document


def read_baseline(path: Path) -> dict[str, Any]:
    """Read and validate a baseline file (``validate_baseline``)."""
    path = Path(path)
    if not path.is_file():
        raise CheckError(f"baseline {path} not found (write one with --update-baseline)")
    return validate_baseline(_read_json(path, "baseline"), path)

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
        raise CheckError("the run and the baseline share no rate to compare")
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


def baseline_for(document: dict[str, Any], detector: str, path: Path | str = "baseline") -> dict[str, Any]:
    """The baseline of ``detector`` in a baseline file's contents; ``CheckError`` naming those it has."""
    if "baselines" not in document:
        return document
    try:
        return document["baselines"][detector]
    except KeyError:
        have = ", ".join(sorted(document["baselines"])) or "none"
        raise CheckError(f"{path} has no baseline for detector {detector!r} (it has: {have})") from None


def write_baseline(summary: dict[str, Any], path: Path) -> None:
    """Set the baseline of the run's detector in ``path`` (created if missing), keeping the other detectors'.
    An existing file must be a valid baseline (``CheckError`` otherwise: it is not silently replaced)."""
    path = Path(path)
    document: dict[str, Any] = {"baselines": {}}
    if path.is_file():
        old = read_baseline(path)
        if "baselines" in old:
            document = old
    document["baselines"][summary["detector"]] = baseline_from_summary(summary)
    document["baselines"] = dict(sorted(document["baselines"].items()))
    atomic_write_text(path, json.dumps(document, indent=2) + "\n")
