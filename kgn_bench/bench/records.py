"""Typed trial and attempt records: what ``run_trial`` returns and what one line of ``trials.jsonl`` holds.

A record's JSON form (``to_json``) is the contract that resume, baselines (``fingerprint``) and
``kgn-bench eval failures`` rest on, so its keys, their order and their values never change for a shape
that exists. The format version is not written into the records (their bytes stay as they were): it is
``RECORD_VERSION`` for records written now, and inferred from a record's keys when one is read
(``from_json``). Shapes, oldest first:

1. trial ``index, protocol, objects, placed, removed, attempts, timing``; attempt ``success, reason,
   object, candidates, selected, score, rejected, detail, sim_time``.
2. the trial gains ``placed_objects`` (the names of the objects on the table once the scene settled) after
   ``placed``; read from version 1 it defaults to every object (``objects``).
3. ``pile`` and ``packed`` trials gain ``fell_at_setup`` and ``fallen`` after ``attempts`` (other protocols'
   records stay as they were); absent, they are None (not a clutter round), counted as 0 in totals.
4. the attempt gains ``grasp`` (the executed grasp, world frame: position m, then unit quaternion w, x, y, z)
   and ``width`` (m) after ``score``; read from an older record both are None (not recorded).

A record read in an older shape writes back in that shape (``version``), so its fingerprint is unchanged.
Shapes 2 and 3 are the same outside pile and packed records, so a record of either reads as version 3; an
attempt without ``grasp`` reads as version 3 too (attempts did not change before version 4).
Scores, grasps and widths are as ``run_trial`` rounded them (6 decimals); ``sim_time`` is simulated seconds
(3 decimals); ``timing`` is wall seconds per stage (4 decimals), the only part that varies between runs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from kgn_bench.errors import KGNBenchError

__all__ = ["RECORD_VERSION", "AttemptRecord", "RecordError", "TrialRecord"]

RECORD_VERSION = 4
"""The shape of the records written by this code (see the module docstring for every shape)."""

_ATTEMPT_KEYS = ("success", "reason", "object", "candidates", "selected", "score", "rejected", "detail", "sim_time")
_TRIAL_KEYS = ("index", "protocol", "objects", "placed", "removed", "attempts", "timing")


class RecordError(KGNBenchError, ValueError):
    """A JSON value that is not a trial or attempt record of any known shape."""


def _require(d: Any, keys: tuple[str, ...], what: str) -> None:
    if not isinstance(d, dict):
        raise RecordError(f"{what} must be a JSON object, got {type(d).__name__}")
    missing = [k for k in keys if k not in d]
    if missing:
        raise RecordError(f"{what} has no {', '.join(missing)}")


@dataclass
class AttemptRecord:
    """One attempt of a trial: its outcome (``success``; else the failure ``reason`` and ``detail``), the
    object it took (name, or None), the detector's candidate count, the selected candidate's index and score,
    the executed ``grasp`` (world frame ``[x, y, z, qw, qx, qy, qz]``) and ``width`` (m), the selector's
    rejections per reason (candidates) and the simulated seconds it took. ``version``: the shape it was
    written in (not part of the JSON)."""

    success: bool
    reason: str | None
    object: str | None
    candidates: int
    selected: int | None
    score: float | None
    grasp: list[float] | None
    width: float | None
    rejected: dict[str, int]
    detail: str
    sim_time: float
    version: int = field(default=RECORD_VERSION, repr=False)

    @classmethod
    def failed(cls, reason: str, detail: str) -> AttemptRecord:
        """An attempt that ended before anything was detected or executed (a fault)."""
        return cls(False, reason, None, 0, None, None, None, None, {}, detail, 0.0)

    def to_json(self) -> dict[str, Any]:
        """The attempt as written in ``trials.jsonl``, in the shape it was written in."""
        d: dict[str, Any] = {"success": self.success, "reason": self.reason, "object": self.object,
                             "candidates": self.candidates, "selected": self.selected, "score": self.score}
        if self.version >= 4:
            d["grasp"] = self.grasp
            d["width"] = self.width
        d.update(rejected=self.rejected, detail=self.detail, sim_time=self.sim_time)
        return d

    @classmethod
    def from_json(cls, d: Any) -> AttemptRecord:
        """An attempt of any shape; ``RecordError`` if ``d`` is none."""
        _require(d, _ATTEMPT_KEYS, "an attempt record")
        version = 4 if "grasp" in d else 3
        return cls(d["success"], d["reason"], d["object"], d["candidates"], d["selected"], d["score"],
                   d.get("grasp"), d.get("width"), d["rejected"], d["detail"], d["sim_time"], version)


@dataclass
class TrialRecord:
    """One finished trial: its ``index``, ``protocol``, the ``objects`` built into the scene (names), how many
    and which stayed on the table once it settled (``placed``, ``placed_objects``), how many went into the bin
    (``removed``), the ``attempts`` in order, for pile and packed rounds the objects that left the table while
    the scene was built (``fell_at_setup``) and during the round (``fallen``; both None for other protocols),
    and wall seconds per stage (``timing``). ``version``: the shape it was written in (not part of the JSON)."""

    index: int
    protocol: str
    objects: list[str]
    placed: int
    placed_objects: list[str]
    removed: int
    attempts: list[AttemptRecord]
    timing: dict[str, float]
    fell_at_setup: int | None = None
    fallen: int | None = None
    version: int = field(default=RECORD_VERSION, repr=False)

    @property
    def successes(self) -> int:
        """Attempts that succeeded."""
        return sum(a.success for a in self.attempts)

    def to_json(self) -> dict[str, Any]:
        """The trial as written in ``trials.jsonl``, in the shape it was written in (timing included)."""
        d: dict[str, Any] = {"index": self.index, "protocol": self.protocol, "objects": self.objects,
                             "placed": self.placed}
        if self.version >= 2:
            d["placed_objects"] = self.placed_objects
        d.update(removed=self.removed, attempts=[a.to_json() for a in self.attempts])
        if self.fell_at_setup is not None or self.fallen is not None:
            d.update(fell_at_setup=self.fell_at_setup, fallen=self.fallen)
        d["timing"] = self.timing
        return d

    @classmethod
    def from_json(cls, d: Any) -> TrialRecord:
        """A trial of any shape (older ones get their documented defaults); ``RecordError`` if ``d`` is none."""
        _require(d, _TRIAL_KEYS, "a trial record")
        if not isinstance(d["attempts"], list):
            raise RecordError("a trial record's attempts must be a list")
        attempts = [AttemptRecord.from_json(a) for a in d["attempts"]]
        if "placed_objects" not in d:
            version = 1
        elif any(a.version < 4 for a in attempts):
            version = 3
        else:
            version = RECORD_VERSION
        return cls(d["index"], d["protocol"], d["objects"], d["placed"], d.get("placed_objects", d["objects"]),
                   d["removed"], attempts, d["timing"], d.get("fell_at_setup"), d.get("fallen"), version)
