"""Wilson intervals against known values, and run summaries of hand-built trial records."""

import json
import math
import random

import pytest

from kgn_bench.bench.attempt import FAILURE_REASONS
from kgn_bench.bench.records import TrialRecord
from kgn_bench.bench.selector import REJECTIONS
from kgn_bench.bench.stats import Rate, summarise, summary_markdown, wilson_interval

Z95 = 1.959963984540054  # the 97.5 % normal quantile


@pytest.mark.parametrize(
    "k, n, low, high",
    [
        (0, 10, 0.0, 0.2775),
        (10, 10, 0.7225, 1.0),
        (5, 10, 0.2366, 0.7634),
        (1, 2, 0.0945, 0.9055),
        (57, 60, 0.8630, 0.9829),
        (20, 60, 0.2273, 0.4594),
    ],
)
def test_wilson_known_values(k, n, low, high):
    lo, hi = wilson_interval(k, n)
    assert lo == pytest.approx(low, abs=1e-3) and hi == pytest.approx(high, abs=1e-3)
    assert 0.0 <= lo <= k / n <= hi + 1e-12 and hi <= 1.0  # k = n gives 1 − 1e-16 (rounding)


@pytest.mark.parametrize("k, n", [(1, 3), (4, 7), (33, 50), (199, 200)])
def test_wilson_bounds_solve_the_score_equation(k, n):
    """Each bound p satisfies (p̂ − p)² = z² p (1 − p) / n, the definition of the score interval."""
    p_hat = k / n
    for p in wilson_interval(k, n):
        assert (p_hat - p) ** 2 == pytest.approx(Z95**2 * p * (1 - p) / n, rel=1e-9, abs=1e-15)


def test_wilson_empty_and_symmetry():
    assert wilson_interval(0, 0) == (0.0, 1.0)
    lo, hi = wilson_interval(3, 10)
    lo2, hi2 = wilson_interval(7, 10)
    assert lo == pytest.approx(1 - hi2) and hi == pytest.approx(1 - lo2)
    # wider with a larger z, narrower with more trials at the same rate
    assert wilson_interval(3, 10, confidence=0.99)[0] < lo
    assert wilson_interval(30, 100)[1] - wilson_interval(30, 100)[0] < hi - lo


def test_rate_dict_round_trip_and_text():
    r = Rate(5, 10)
    d = r.to_dict()
    assert d == {"k": 5, "n": 10, "rate": 0.5, "low": round(r.interval[0], 6), "high": round(r.interval[1], 6)}
    assert Rate.from_dict(json.loads(json.dumps(d))) == r
    assert str(r) == "50.0 % [23.7, 76.3] (5/10)"
    empty = Rate(0, 0).to_dict()
    assert empty["rate"] is None and (empty["low"], empty["high"]) == (0.0, 1.0)
    assert math.isnan(Rate(0, 0).value)


def _attempt(success, reason=None, rejected=None, obj=None):
    """An attempt in the shape written before grasps were recorded (``records`` version 3)."""
    return {"success": success, "reason": None if success else reason, "object": obj, "candidates": 0,
            "selected": None, "score": None, "rejected": rejected or {}, "detail": "", "sim_time": 0.0}


def _trials(dicts):
    """Hand-built trials read as records (no timing; ``placed_objects`` where given, as in older records)."""
    return [TrialRecord.from_json({**d, "timing": {}}) for d in dicts]


SINGLE = [
    {"index": 0, "protocol": "single_object", "objects": ["cuboid"], "placed": 1, "removed": 1,
     "attempts": [_attempt(True, rejected={"width": 2, "collision": 1})]},
    {"index": 1, "protocol": "single_object", "objects": ["cuboid"], "placed": 1, "removed": 0,
     "attempts": [_attempt(False, "missed", {"collision": 4})]},
    {"index": 2, "protocol": "single_object", "objects": ["sphere"], "placed": 1, "removed": 1,
     "attempts": [_attempt(True)]},
    {"index": 3, "protocol": "single_object", "objects": ["sphere"], "placed": 1, "removed": 1,
     "attempts": [_attempt(True, rejected={"ik": 3})]},
    {"index": 4, "protocol": "single_object", "objects": ["ring"], "placed": 1, "removed": 0,
     "attempts": [_attempt(False, "no_candidate", {"enclosure": 5})]},
]  # fmt: skip
SINGLE = _trials(SINGLE)
RUN_SINGLE = {"task": "t", "protocol": "single_object", "detector": "oracle", "seed": 3}


def test_summarise_single_object():
    s = summarise(SINGLE, RUN_SINGLE)
    assert {k: s[k] for k in RUN_SINGLE} == RUN_SINGLE
    assert s["trials"] == 5 and s["attempts"] == 5
    assert set(s["rates"]) == {"success"}
    assert s["rates"]["success"] == Rate(3, 5).to_dict()
    assert list(s["failures"]) == list(FAILURE_REASONS)
    assert s["failures"] == {**dict.fromkeys(FAILURE_REASONS, 0), "missed": 1, "no_candidate": 1}
    assert list(s["per_object"]) == ["cuboid", "ring", "sphere"]  # sorted by name
    assert s["per_object"]["cuboid"] == Rate(1, 2).to_dict()
    assert s["per_object"]["sphere"] == Rate(2, 2).to_dict()
    assert s["per_object"]["ring"] == Rate(0, 1).to_dict()
    assert s["selector_rejections"] == {"workspace": 0, "repeat": 0, "width": 2, "collision": 5, "occluded": 0,
                                        "enclosure": 5, "ik": 3}
    assert list(s["selector_rejections"]) == list(REJECTIONS)
    json.dumps(s)  # plain JSON data


MULTI = [
    {"index": 0, "protocol": "multi_object", "objects": ["cuboid", "ring", "stick"], "placed": 3, "removed": 3,
     "attempts": [_attempt(True, obj="ring"), _attempt(False, "dropped_lift", obj="cuboid"),
                  _attempt(True, obj="cuboid"), _attempt(True, obj="stick")]},
    {"index": 1, "protocol": "multi_object", "objects": ["sphere", "cylinder", "ring"], "placed": 3, "removed": 1,
     "attempts": [_attempt(True, obj="sphere"), _attempt(False, "collision"), _attempt(False, "collision"),
                  _attempt(False, "unreachable", {"ik": 7})]},
    {"index": 2, "protocol": "multi_object", "objects": ["stick", "cuboid", "cylinder"], "placed": 2, "removed": 2,
     "placed_objects": ["stick", "cylinder"],
     "attempts": [_attempt(True, obj="stick"), _attempt(True, obj="cylinder")]},
]  # fmt: skip
MULTI = _trials(MULTI)


def test_summarise_multi_object():
    s = summarise(MULTI, {"task": "m", "protocol": "multi_object", "detector": "random", "seed": 0})
    assert s["trials"] == 3 and s["attempts"] == 10
    assert s["rates"]["success"] == Rate(6, 10).to_dict()
    assert s["rates"]["clear"] == Rate(6, 8).to_dict()  # removed / placed
    assert s["rates"]["scenes_cleared"] == Rate(2, 3).to_dict()
    assert s["failures"] == {**dict.fromkeys(FAILURE_REASONS, 0), "dropped_lift": 1, "collision": 2,
                             "unreachable": 1}  # fmt: skip
    # objects of the type put in the bin / placed; the cuboid that fell off in trial 2 was never placed
    assert s["per_object"] == {"cuboid": Rate(1, 1).to_dict(), "cylinder": Rate(1, 2).to_dict(),
                               "ring": Rate(1, 2).to_dict(), "sphere": Rate(1, 1).to_dict(),
                               "stick": Rate(2, 2).to_dict()}
    assert s["selector_rejections"]["ik"] == 7


@pytest.mark.parametrize("records, protocol", [(SINGLE, "single_object"), (MULTI, "multi_object")])
def test_summary_does_not_depend_on_record_order(records, protocol):
    run = {"task": "x", "protocol": protocol, "detector": "oracle", "seed": 1}
    expected = json.dumps(summarise(records, run))
    shuffled = list(records)
    for seed in range(4):
        random.Random(seed).shuffle(shuffled)
        assert json.dumps(summarise(shuffled, run)) == expected
        assert summary_markdown(summarise(shuffled, run)) == summary_markdown(json.loads(expected))


def test_summary_markdown_lists_rates_objects_and_failures():
    s = summarise(SINGLE, RUN_SINGLE)
    md = summary_markdown(s)
    assert md.startswith("# t: oracle (single_object, seed 3)\n")
    assert "5 trials, 5 attempts." in md
    assert "| success | 60.0 % [23.1, 88.2] | 3 / 5 |" in md
    assert "| cuboid | 50.0 % [9.5, 90.5] | 1 / 2 |" in md
    assert "| missed | 1 |" in md and "| collision | 5 |" in md


PILE = _trials([
    {"index": 0, "protocol": "pile", "objects": ["cuboid", "ring", "stick"], "placed": 2,
     "placed_objects": ["cuboid", "ring"], "removed": 1, "fell_at_setup": 1, "fallen": 0,
     "attempts": [_attempt(True, obj="ring"), _attempt(False, "missed"), _attempt(False, "no_candidate")]},
    {"index": 1, "protocol": "pile", "objects": ["sphere", "cylinder"], "placed": 2,
     "placed_objects": ["sphere", "cylinder"], "removed": 2, "fell_at_setup": 0, "fallen": 1,
     "attempts": [_attempt(True, obj="sphere"), _attempt(True, obj="cylinder")]},
])  # fmt: skip


def test_summarise_pile_counts_executed_grasps_and_fallen_objects():
    s = summarise(PILE, {"task": "p", "protocol": "pile", "detector": "kgnv2", "seed": 0})
    assert s["attempts"] == 4 and s["rates"]["success"] == Rate(3, 4).to_dict()  # no_candidate executed nothing
    assert s["failures"]["no_candidate"] == 1 and s["failures"]["missed"] == 1
    assert s["rates"]["clear"] == Rate(3, 4).to_dict() and s["rates"]["scenes_cleared"] == Rate(1, 2).to_dict()
    assert (s["fell_at_setup"], s["fallen"]) == (1, 1)
    assert s["per_object"]["cuboid"] == Rate(0, 1).to_dict() and "stick" not in s["per_object"]
    assert "fallen" not in summarise(MULTI, {"task": "m", "protocol": "multi_object"})
