"""The benchmark protocols, each described once: how a trial's scene is built, when its round ends, and how
its records are counted and reported.

``config`` validates a task's protocol against ``PROTOCOLS``; the trial loop (``bench.trial``), the statistics
(``bench.stats``), the runner and the report read a ``Protocol``'s fields instead of comparing names. Adding a
protocol means one entry here, plus its arrangement function in ``bench.trial.ARRANGEMENTS`` when it arranges
the objects in a new way. Foundation level: this module imports nothing from the project.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["CLEARANCE_PROTOCOLS", "CLUTTER_PROTOCOLS", "PROTOCOLS", "Protocol", "protocol"]


@dataclass(frozen=True)
class Protocol:
    """How trials of one protocol run and count.

    ``one_object``: a trial is one object of the set (trial ``index`` takes ``objects[index // trials]``, so a
    task has ``trials × len(objects)`` trials) and one attempt; otherwise ``objects_per_scene`` objects and up
    to ``max_attempts_per_object × objects`` attempts, the arm parked and the scene settled between them.
    ``arrangement``: how the objects are put on the table (a key of ``bench.trial.ARRANGEMENTS``);
    ``pile_box``: the work cell carries the box the objects are dropped into.
    ``clearance``: a trial is a round that tries to clear the table, with a clear rate (removed / placed) and
    a scenes-cleared rate in the summary; the per-object rate is objects put in the bin / placed, else
    successes / attempts. ``clutter``: VGN/GIGA's clutter round, the report's hard tier: the round ends as soon
    as an attempt executes nothing, the success rate (GSR) counts executed grasps only, and the records count
    the objects that left the table (``fell_at_setup``, ``fallen``). ``giga``: GIGA's own rounds
    (``kgn_bench.giga``): objects drawn with replacement and sized GIGA's way, an object whose origin leaves
    the workspace cube leaves the round (at set-up it never entered it), and every detector sees the depth of
    the cube only and grasps in it, as GIGA crops every method's input to it; reported in a tier of their own."""

    name: str
    one_object: bool = False
    arrangement: str = "spread"
    pile_box: bool = False
    clearance: bool = True
    clutter: bool = False
    giga: bool = False

    @property
    def draws_with_replacement(self) -> bool:
        """Whether a round's objects are drawn from the set with replacement (GIGA's), else without while the
        set allows."""
        return self.giga

    @property
    def workspace_cube(self) -> bool:
        """Whether objects outside GIGA's workspace cube leave the round (``giga.in_workspace``), the depth a
        detector sees is cropped to the cube (``camera.crop_depth``) and the selector takes grasps in it only."""
        return self.giga

    @property
    def park_between_attempts(self) -> bool:
        """Whether the arm parks (and the scene settles) after each attempt: every protocol of several attempts."""
        return not self.one_object

    @property
    def ends_when_nothing_executed(self) -> bool:
        """Whether an attempt that executed nothing (no candidate, unreachable, ...) ends the round (VGN)."""
        return self.clutter

    @property
    def gsr_executed_only(self) -> bool:
        """Whether the summary's success rate counts only attempts that executed a grasp (VGN/GIGA's GSR)."""
        return self.clutter

    @property
    def counts_fallen(self) -> bool:
        """Whether its records carry ``fell_at_setup`` and ``fallen``."""
        return self.clutter

    @property
    def per_object_meaning(self) -> str:
        """What the per-object rate counts: ``success`` (one object a trial) or ``put in the bin``."""
        return "success" if self.one_object else "put in the bin"

    @property
    def report_tier(self) -> str:
        """The report table its runs go to: ``giga`` (GIGA's rounds), ``hard`` (clutter) or ``main``."""
        return "giga" if self.giga else "hard" if self.clutter else "main"


PROTOCOLS: dict[str, Protocol] = {p.name: p for p in (
    Protocol("single_object", one_object=True, clearance=False),
    Protocol("multi_object"),
    Protocol("pile", arrangement="pile", pile_box=True, clutter=True),
    Protocol("packed", arrangement="packed", clutter=True),
    Protocol("giga_pile", arrangement="giga_pile", pile_box=True, clutter=True, giga=True),
    Protocol("giga_packed", arrangement="giga_packed", clutter=True, giga=True),
)}
"""Every protocol by name, in the order the documentation lists them."""

CLEARANCE_PROTOCOLS = tuple(name for name, p in PROTOCOLS.items() if p.clearance)
"""Protocols whose trial is a round of attempts on several objects (success rate and clear rate)."""

CLUTTER_PROTOCOLS = tuple(name for name, p in PROTOCOLS.items() if p.clutter)
"""VGN/GIGA's clutter rounds: the hard tier."""

_OTHER = Protocol("?", clearance=False)
"""How a summary of an unknown (or unrecorded) protocol is read: not clearance, not clutter, per-object rates
as objects put in the bin / placed (as the statistics always read a protocol that is not ``single_object``)."""


def protocol(name: str | None) -> Protocol:
    """The protocol ``name``; for a name that is none of ``PROTOCOLS`` (a summary without one), a description
    with every feature off except the per-object meaning ``put in the bin``."""
    return PROTOCOLS.get(name or "", _OTHER)
