"""The fingerprint of a run: what its records say, less their timings, trial by trial.

A run's records are a pure function of its identity (task config, detector, seed, trial count) and its
environment (package versions, and the CPU unless the portable kernel set is in force, ``kgn_bench.kernels``).
Two runs with the same identity in the same environment therefore give the same records, bit for bit, and
any difference means the code changed what it does. The fingerprint holds, per trial, the SHA-256 of its
record without the ``timing`` field (canonical JSON: sorted keys, no spaces) and a short outcome line per
attempt (object, outcome, failure reason, score), so that a difference can be told in words; and the SHA-256
of the run's identity (``run.json`` less ``commit`` and ``environment``) with the environment itself.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any

from .records import TrialRecord

__all__ = ["AttemptLine", "Fingerprint", "TrialPrint", "canonical_sha256", "compare_trials", "fingerprint"]

VERSION = 1
"""Version of the fingerprint's JSON form."""


def canonical_sha256(value: Any) -> str:
    """SHA-256 hex digest of ``value`` as canonical JSON (sorted keys, compact separators, UTF-8)."""
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class AttemptLine:
    """One attempt, as the fingerprint keeps it: the object aimed at, success, failure reason and score."""

    object: str | None
    success: bool
    reason: str | None
    score: float | None

    def __str__(self) -> str:
        outcome = "success" if self.success else (self.reason or "failure")
        score = "" if self.score is None else f" (score {self.score:.6f})"
        return f"{self.object or '-'}: {outcome}{score}"


@dataclass(frozen=True)
class TrialPrint:
    """A trial's record digest (``sha256``, timings left out) and its attempts."""

    index: int
    sha256: str
    attempts: tuple[AttemptLine, ...]

    def to_dict(self) -> dict[str, Any]:
        return {"index": self.index, "sha256": self.sha256,
                "attempts": [[a.object, a.success, a.reason, a.score] for a in self.attempts]}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrialPrint:
        return cls(int(d["index"]), str(d["sha256"]), tuple(AttemptLine(*a) for a in d["attempts"]))


@dataclass(frozen=True)
class Fingerprint:
    """A run's identity digest, environment and per-trial prints (in index order)."""

    identity_sha256: str
    environment: dict[str, Any]
    trials: tuple[TrialPrint, ...]

    def to_dict(self) -> dict[str, Any]:
        return {"version": VERSION, "identity_sha256": self.identity_sha256, "environment": self.environment,
                "trials": [t.to_dict() for t in self.trials]}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Fingerprint:
        if d.get("version") != VERSION:
            raise ValueError(f"fingerprint version {d.get('version')!r} is not {VERSION}")
        return cls(str(d["identity_sha256"]), dict(d.get("environment") or {}),
                   tuple(TrialPrint.from_dict(t) for t in d["trials"]))


def _trial_print(record: TrialRecord) -> TrialPrint:
    """The digest of the record's JSON form (in the shape it was written in) less ``timing``, and its attempts."""
    body = {k: v for k, v in record.to_json().items() if k != "timing"}
    attempts = tuple(AttemptLine(a.object, bool(a.success), a.reason, a.score) for a in record.attempts)
    return TrialPrint(int(record.index), canonical_sha256(body), attempts)


def fingerprint(run: dict[str, Any], records: list[TrialRecord]) -> Fingerprint:
    """The fingerprint of a run from its ``run.json`` contents and its trial records."""
    identity = {k: v for k, v in run.items() if k not in ("commit", "environment")}
    trials = tuple(_trial_print(r) for r in sorted(records, key=lambda r: r.index))
    return Fingerprint(canonical_sha256(identity), dict(run.get("environment") or {}), trials)


def _attempt_change(k: int, a: AttemptLine | None, b: AttemptLine | None) -> str:
    if a is None:
        return f"attempt {k}: new, {b}"
    if b is None:
        return f"attempt {k}: gone (was {a})"
    return f"attempt {k}: {a} → {b}"


def compare_trials(baseline: Fingerprint, run: Fingerprint) -> list[str]:
    """One line per trial whose record differs (or that only one side has), saying how; empty if the runs'
    records are identical."""
    base = {t.index: t for t in baseline.trials}
    mine = {t.index: t for t in run.trials}
    lines = []
    for index in sorted(base.keys() | mine.keys()):
        a, b = base.get(index), mine.get(index)
        if a is None or b is None:
            lines.append(f"trial {index}: only in the {'run' if a is None else 'baseline'}")
            continue
        if a.sha256 == b.sha256:
            continue
        n = max(len(a.attempts), len(b.attempts))
        changed = [_attempt_change(k + 1, a.attempts[k] if k < len(a.attempts) else None,
                                   b.attempts[k] if k < len(b.attempts) else None)
                   for k in range(n) if (a.attempts[k:k + 1] or None) != (b.attempts[k:k + 1] or None)]
        lines.append(f"trial {index}: " + ("; ".join(changed) if changed else
                                            "same outcomes and scores, other fields of the record differ"))
    return lines
