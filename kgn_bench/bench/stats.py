"""Rates with Wilson 95 % score intervals, and run summaries built from trial records.

Wilson interval for k successes in n trials, z = 1.96 (``scipy.stats.binomtest(...).proportion_ci``):
``(p̂ + z²/2n ± z·sqrt(p̂(1 − p̂)/n + z²/4n²)) / (1 + z²/n)``. Unlike the normal approximation it stays
inside [0, 1] and is sensible at 0/n and n/n.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import binomtest

from kgn_bench.protocols import Protocol, protocol

from .attempt import FAILURE_REASONS, NOT_EXECUTED
from .records import TrialRecord
from .selector import REJECTIONS

__all__ = ["Rate", "SeededRate", "per_object_meaning", "rate_from_dict", "summarise", "summary_markdown",
           "wilson_interval"]

def wilson_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (scipy); (0, 1) when n = 0."""
    if n == 0:
        return 0.0, 1.0
    ci = binomtest(k, n).proportion_ci(confidence_level=confidence, method="wilson")
    return float(ci.low), float(ci.high)


@dataclass(frozen=True)
class Rate:
    """``k`` of ``n`` with its point estimate and Wilson 95 % interval."""

    k: int
    n: int

    @property
    def value(self) -> float:
        return self.k / self.n if self.n else float("nan")

    @property
    def interval(self) -> tuple[float, float]:
        return wilson_interval(self.k, self.n)

    def to_dict(self) -> dict[str, Any]:
        lo, hi = self.interval
        return {"k": self.k, "n": self.n, "rate": round(self.value, 6) if self.n else None,
                "low": round(lo, 6), "high": round(hi, 6)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Rate:
        return cls(int(d["k"]), int(d["n"]))

    def __str__(self) -> str:
        lo, hi = self.interval
        return f"{100 * self.value:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] ({self.k}/{self.n})"


@dataclass(frozen=True)
class SeededRate(Rate):
    """The rates of several seeds' runs of one cell: ``k`` and ``n`` summed over them (the pooled rate and its
    Wilson interval) and ``per_seed``, each seed's own rate, for GIGA's figure: their mean and population
    standard deviation (numpy's default, ddof = 0, as GIGA's evaluation script computes it)."""

    per_seed: tuple[float, ...] = ()

    @property
    def mean_std(self) -> tuple[float, float]:
        """Mean and population standard deviation of the per-seed rates."""
        v = np.asarray(self.per_seed, dtype=float)
        return float(v.mean()), float(v.std())

    def to_dict(self) -> dict[str, Any]:
        mean, std = self.mean_std
        return {**super().to_dict(), "per_seed": [round(v, 6) for v in self.per_seed], "mean": round(mean, 6),
                "std": round(std, 6)}

    def __str__(self) -> str:
        mean, std = self.mean_std
        return f"{super().__str__()}; {100 * mean:.1f} ± {100 * std:.1f} over {len(self.per_seed)} seeds"


def rate_from_dict(d: dict[str, Any]) -> Rate:
    """A ``Rate``, or a ``SeededRate`` where ``d`` carries ``per_seed`` (``to_dict``'s inverse)."""
    if "per_seed" in d:
        return SeededRate(int(d["k"]), int(d["n"]), tuple(float(v) for v in d["per_seed"]))
    return Rate.from_dict(d)


def per_object_meaning(name: str | None) -> str:
    """What a summary's per-object rate counts under protocol ``name`` (``Protocol.per_object_meaning``):
    ``success`` (single-object trials) or ``put in the bin`` (clearance: objects of the type removed / placed)."""
    return protocol(name).per_object_meaning


def summarise(records: list[TrialRecord], run: dict[str, Any]) -> dict[str, Any]:
    """The deterministic summary of a run: rates, failure counts, per-object rates, selector rejections.

    Per object type: single-object runs give successes / attempts on that object; multi-object runs give
    objects of that type put in the bin / placed (the clear rate per type). In pile and packed runs an
    attempt that executed nothing (``NOT_EXECUTED``: it ended the round) is not an attempt of the success rate
    (GSR), as in VGN/GIGA; it still shows in the failure counts.

    ``run`` is the run's identity (task, detector, seed, ...), copied in. Records are sorted by index, so
    the summary does not depend on the order trials finished in.
    """
    spec = protocol(run.get("protocol"))
    records = sorted(records, key=lambda r: r.index)
    every = [a for r in records for a in r.attempts]
    failures = Counter(a.reason for a in every if not a.success)
    attempts = every
    if spec.gsr_executed_only:  # GSR counts executed grasps only (VGN/GIGA)
        attempts = [a for a in every if a.reason not in NOT_EXECUTED]
    successes = sum(a.success for a in attempts)
    rejected = Counter()
    for a in attempts:
        rejected.update(a.rejected)
    rates = {"success": Rate(successes, len(attempts)).to_dict()}
    if spec.clearance:
        rates["clear"] = Rate(sum(r.removed for r in records), sum(r.placed for r in records)).to_dict()
        rates["scenes_cleared"] = Rate(sum(r.removed == r.placed for r in records), len(records)).to_dict()
    per_object = _per_object_counts(records, spec)
    return {
        **run,
        "trials": len(records),
        "attempts": len(attempts),
        "rates": rates,
        "failures": {reason: failures.get(reason, 0) for reason in FAILURE_REASONS},
        "per_object": {name: Rate(k, n).to_dict() for name, (k, n) in sorted(per_object.items())},
        "selector_rejections": {name: rejected.get(name, 0) for name in REJECTIONS},
        **_clutter_totals(records),
    }


def _per_object_counts(records: list[TrialRecord], spec: Protocol) -> dict[str, list[int]]:
    """``{object: [k, n]}``: for a one-object protocol successes / attempts on the trial's object; otherwise
    objects of the type put in the bin / placed (``placed_objects``; every object in records older than it)."""
    per_object: dict[str, list[int]] = {}
    for r in records:
        if spec.one_object:  # successes / attempts on the trial's one object
            k, n = per_object.setdefault(r.objects[0], [0, 0])
            per_object[r.objects[0]] = [k + sum(a.success for a in r.attempts), n + len(r.attempts)]
        else:  # objects of the type put in the bin / placed
            for name in r.placed_objects:
                per_object.setdefault(name, [0, 0])[1] += 1
            for a in r.attempts:
                if a.success:
                    per_object[a.object][0] += 1
    return per_object


def _clutter_totals(records: list[TrialRecord]) -> dict[str, Any]:
    """Pile and packed runs: objects that left the table while the scene was built, and during the rounds
    (records that count them, ``TrialRecord.fallen`` not None)."""
    if not records or records[0].fallen is None:
        return {}
    return {"fell_at_setup": sum(r.fell_at_setup or 0 for r in records),
            "fallen": sum(r.fallen or 0 for r in records)}


def _rate_row(name: str, d: dict[str, Any]) -> str:
    r = Rate.from_dict(d)
    lo, hi = r.interval
    return f"| {name} | {100 * r.value:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] | {r.k} / {r.n} |"


def summary_markdown(summary: dict[str, Any]) -> str:
    """A human-readable Markdown table of a summary."""
    lines = [f"# {summary.get('task', 'run')}: {summary.get('detector', '?')} "
             f"({summary.get('protocol', '?')}, seed {summary.get('seed', '?')})", "",
             f"{summary['trials']} trials, {summary['attempts']} attempts.", "",
             "| rate | value [Wilson 95 %] | k / n |", "| --- | --- | --- |"]
    lines += [_rate_row(name, d) for name, d in summary["rates"].items()]
    if summary["per_object"]:
        lines += ["", f"| object | {per_object_meaning(summary.get('protocol'))} [Wilson 95 %] | k / n |",
                  "| --- | --- | --- |"]
        lines += [_rate_row(name, d) for name, d in summary["per_object"].items()]
    lines += ["", "| failure reason | attempts |", "| --- | --- |"]
    lines += [f"| {k} | {v} |" for k, v in summary["failures"].items()]
    lines += ["", "| selector rejections (candidates) | count |", "| --- | --- |"]
    lines += [f"| {k} | {v} |" for k, v in summary["selector_rejections"].items()]
    return "\n".join(lines) + "\n"
