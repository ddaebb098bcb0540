"""Regression check of a run against a stored baseline: exact where it can be, statistical where it cannot.

**Exact mode.** A baseline written by ``kgn-bench check --update-baseline`` holds the run's fingerprint
(``fingerprint``: per-trial digests of the records less their timings, the identity digest and the
environment). When the run has the baseline's identity and environment (``environment_differences`` empty:
the same packages and Python, and either the portable kernel set on both sides or the same CPU), its records
must be the baseline's, bit for bit: any trial that differs is a regression (exit 1), and the check says
which trials changed and how. A change that is meant to change records is confirmed by writing a new
baseline.

**Statistical mode.** Otherwise (another environment, a baseline without a fingerprint, or a run checked
against another detector's baseline with ``against``), each rate the two share is tested with Boschloo's
one-sided exact test (``drop_test``): a regression is a p-value below 0.05. Improvements never fail.

A baseline file holds one baseline per detector: ``{"baselines": {detector: {identity..., "rates": {...},
"fingerprint": {...}}}}`` with each rate as ``{"k", "n", ...}``. (A file holding a single baseline at the
top level is read too.)
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from kgn_bench.environment import environment_differences, kernel_set
from kgn_bench.errors import KGNBenchError
from kgn_bench.io import atomic_write_text

from .drop_test import ALPHA, drop_pvalue
from .fingerprint import Fingerprint, compare_trials, fingerprint
from .records import RecordError, TrialRecord
from .stats import Rate

__all__ = ["POWERED_ATTEMPTS", "CheckError", "CheckResult", "CheckRow", "baseline_for", "baseline_from_run",
           "check", "compare", "format_check", "read_baseline", "read_run", "read_summary", "validate_baseline",
           "write_baseline"]

POWERED_ATTEMPTS = 118
"""Attempts (run and baseline alike) from which the statistical test catches a drop from 95 to 85 % with
power ≥ 0.8 (``drop_test.trials_for_power()``)."""


class CheckError(KGNBenchError, ValueError):
    """A run folder or a baseline file that cannot be used (missing, not JSON, of the wrong shape)."""


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


def _read_records(path: Path) -> list[TrialRecord]:
    """Every line of a finished run's ``trials.jsonl`` as a record (of any shape); ``CheckError`` naming the
    first line that is not one."""
    if not path.is_file():
        raise CheckError(f"{path} not found: run the benchmark first")
    records = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            raise CheckError(f"{path}: line {n} is not valid JSON") from None
        if not isinstance(record, dict) or not isinstance(record.get("index"), int):
            raise CheckError(f"{path}: line {n} is not a trial record")
        try:
            records.append(TrialRecord.from_json(record))
        except RecordError as e:
            raise CheckError(f"{path}: line {n} is not a trial record ({e})") from None
    return records


@dataclass(frozen=True)
class RunFiles:
    """What the check reads of a run folder: its summary, its ``run.json``, its trial records and their
    fingerprint."""

    summary: dict[str, Any]
    run: dict[str, Any]
    records: list[TrialRecord]
    fingerprint: Fingerprint


def read_run(folder: Path) -> RunFiles:
    """A finished run folder's summary, identity and fingerprint; ``CheckError`` naming what is missing."""
    folder = Path(folder)
    summary = read_summary(folder)
    run = _read_json(folder / "run.json", "run identity")
    if not isinstance(run, dict):
        raise CheckError(f"{folder / 'run.json'} is not a run identity")
    records = _read_records(folder / "trials.jsonl")
    if isinstance(run.get("trials"), int) and len(records) < run["trials"]:
        raise CheckError(f"{folder} is not finished ({len(records)} of {run['trials']} trials): rerun it to resume")
    return RunFiles(summary, run, records, fingerprint(run, records))


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
        if "fingerprint" in entry:
            try:
                Fingerprint.from_dict(entry["fingerprint"])
            except (KeyError, TypeError, ValueError) as e:
                raise CheckError(f"baseline {path} [{detector}]: unreadable fingerprint ({e})") from None
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
    """One rate of the statistical test: the baseline's, the run's, and the one-sided p-value of a drop."""

    name: str
    baseline: Rate
    run: Rate

    @property
    def pvalue(self) -> float:
        return drop_pvalue(self.run, self.baseline)

    @property
    def regressed(self) -> bool:
        return self.pvalue < ALPHA


def compare(summary: dict[str, Any], baseline: dict[str, Any]) -> list[CheckRow]:
    """One row per rate present in both; ``CheckError`` if they share none."""
    rows = [CheckRow(name, Rate.from_dict(b), Rate.from_dict(summary["rates"][name]))
            for name, b in baseline["rates"].items() if name in summary["rates"]]
    if not rows:
        raise CheckError("the run and the baseline share no rate to compare")
    return rows


@dataclass(frozen=True)
class CheckResult:
    """The verdict: ``mode`` ``exact`` (records compared trial by trial) or ``statistical`` (``reason`` says
    why not exact), the rows of the statistical test, and in exact mode the trials that changed."""

    mode: str
    rows: list[CheckRow]
    reason: str = ""
    changes: list[str] = field(default_factory=list)
    trials: int = 0

    @property
    def regressed(self) -> bool:
        if self.mode == "exact":
            return bool(self.changes)
        return any(r.regressed for r in self.rows)


def _not_exact(run: RunFiles, baseline: dict[str, Any], against: str | None) -> str:
    """Why the run cannot be compared with ``baseline`` record by record ('' if it can)."""
    if against is not None and against != run.summary["detector"]:
        return f"the run's detector {run.summary['detector']!r} is checked against {against!r}'s baseline"
    if "fingerprint" not in baseline:
        return "the baseline has no fingerprint (write one with --update-baseline)"
    base = Fingerprint.from_dict(baseline["fingerprint"])
    if base.identity_sha256 != run.fingerprint.identity_sha256:
        differ = [k for k in IDENTITY if k in baseline and run.summary.get(k) != baseline.get(k)]
        return "the run's identity differs from the baseline's" + (f" ({', '.join(differ)})" if differ else
                                                                    " (its settings, weights or objects)")
    diff = environment_differences(base.environment, run.fingerprint.environment)
    if diff:
        return "the environment differs: " + "; ".join(diff)
    return ""


def check(run: RunFiles, baseline: dict[str, Any], against: str | None = None) -> CheckResult:
    """Check ``run`` against the baseline entry ``baseline`` (module docstring). ``against`` names the
    detector whose baseline it is when that is not the run's own (statistical mode only)."""
    rows = compare(run.summary, baseline)
    reason = _not_exact(run, baseline, against)
    if reason:
        return CheckResult("statistical", rows, reason)
    changes = compare_trials(Fingerprint.from_dict(baseline["fingerprint"]), run.fingerprint)
    return CheckResult("exact", rows, changes=changes, trials=len(run.fingerprint.trials))


def format_check(result: CheckResult, run: RunFiles) -> str:
    """The check's report: the mode and why, the trials that changed (exact mode), the rate table."""
    env = run.fingerprint.environment
    if result.mode == "exact":
        where = f"{kernel_set(env)} kernels" + ("" if kernel_set(env) != "native" else f" on {env.get('cpu')}")
        head = [f"exact check: same identity and environment as the baseline ({where}), {result.trials} trials "
                "compared record by record"]
        if result.changes:
            head += [f"{len(result.changes)} of {result.trials} trials differ from the baseline:"]
            head += [f"  {line}" for line in result.changes]
            head += ["REGRESSION: the records changed (if the change is intended, write the baseline anew with "
                     "--update-baseline)"]
        else:
            head += ["records identical to the baseline's"]
    else:
        head = [f"statistical check (Boschloo's one-sided exact test, α {ALPHA}): {result.reason}"]
    lines = [*head, f"{'rate':<16} {'baseline':<32} {'run':<32} {'p (drop)':>9}  verdict"]
    for r in result.rows:
        verdict = "REGRESSION" if result.mode == "statistical" and r.regressed else "ok"
        lines.append(f"{r.name:<16} {r.baseline!s:<32} {r.run!s:<32} {r.pvalue:>9.4f}  {verdict}")
    if result.mode == "statistical":
        small = [r.name for r in result.rows if min(r.run.n, r.baseline.n) < POWERED_ATTEMPTS]
        if small:
            lines.append(f"note: {', '.join(small)} rest on fewer than {POWERED_ATTEMPTS} attempts a side, too few "
                         "to catch a 10-point drop of a 95 % detector with 80 % power")
    return "\n".join(lines)


def baseline_from_run(run: RunFiles) -> dict[str, Any]:
    """A baseline entry: the run's identity fields, its rates and its fingerprint."""
    summary = run.summary
    return {**{k: summary[k] for k in IDENTITY if k in summary}, "rates": summary["rates"],
            "fingerprint": run.fingerprint.to_dict()}


def baseline_for(document: dict[str, Any], detector: str, path: Path | str = "baseline") -> dict[str, Any]:
    """The baseline of ``detector`` in a baseline file's contents; ``CheckError`` naming those it has."""
    if "baselines" not in document:
        return document
    try:
        return document["baselines"][detector]
    except KeyError:
        have = ", ".join(sorted(document["baselines"])) or "none"
        raise CheckError(f"{path} has no baseline for detector {detector!r} (it has: {have})") from None


def write_baseline(run: RunFiles, path: Path) -> None:
    """Set the baseline of the run's detector in ``path`` (created if missing), keeping the other detectors'.
    An existing file must be a valid baseline (``CheckError`` otherwise: it is not silently replaced)."""
    path = Path(path)
    document: dict[str, Any] = {"baselines": {}}
    if path.is_file():
        old = read_baseline(path)
        if "baselines" in old:
            document = old
    document["baselines"][run.summary["detector"]] = baseline_from_run(run)
    document["baselines"] = dict(sorted(document["baselines"].items()))
    atomic_write_text(path, json.dumps(document, indent=2) + "\n")
