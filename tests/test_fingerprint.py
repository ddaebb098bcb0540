"""Run fingerprints: record digests without timings, and differences told trial by trial."""

import copy

from kgn_bench.bench.fingerprint import Fingerprint, canonical_sha256, compare_trials, fingerprint
from kgn_bench.bench.records import TrialRecord


def _record(index, scores=(0.7, 0.6), reasons=(None, None), timing=1.0):
    attempts = [{"success": r is None, "reason": r, "object": f"obj{k}", "candidates": 10, "selected": 0,
                 "score": s, "grasp": None, "width": None, "rejected": {}, "detail": "", "sim_time": 0.5}
                for k, (s, r) in enumerate(zip(scores, reasons, strict=True))]
    return TrialRecord.from_json({"index": index, "protocol": "multi_object", "objects": ["obj0", "obj1"],
                                  "placed": 2, "placed_objects": ["obj0", "obj1"], "removed": 2,
                                  "attempts": attempts, "timing": {"detect": timing}})


RUN = {"task": "ci", "detector": "kgnv2", "seed": 0, "trials": 2, "commit": "abc",
       "environment": {"python": "3.11.7", "kernels": {"set": "x86-64-v3"}}}


def test_timings_commit_and_order_do_not_change_the_fingerprint():
    a = fingerprint(RUN, [_record(0), _record(1)])
    b = fingerprint({**RUN, "commit": "def"}, [_record(1, timing=9.0), _record(0, timing=3.0)])
    assert a.trials == b.trials and a.identity_sha256 == b.identity_sha256
    assert compare_trials(a, b) == []
    assert Fingerprint.from_dict(a.to_dict()) == a


def test_the_identity_digest_covers_the_task_but_not_the_environment():
    a = fingerprint(RUN, [_record(0)])
    assert fingerprint({**RUN, "environment": {}}, [_record(0)]).identity_sha256 == a.identity_sha256
    assert fingerprint({**RUN, "seed": 1}, [_record(0)]).identity_sha256 != a.identity_sha256


def test_a_changed_score_outcome_or_field_is_told_per_trial():
    base = fingerprint(RUN, [_record(0), _record(1)])
    run = fingerprint(RUN, [_record(0, scores=(0.7, 0.61)), _record(1, reasons=(None, "missed"))])
    lines = compare_trials(base, run)
    assert lines == ["trial 0: attempt 2: obj1: success (score 0.600000) → obj1: success (score 0.610000)",
                     "trial 1: attempt 2: obj1: success (score 0.600000) → obj1: missed (score 0.600000)"]
    other = _record(0)
    other.removed = 1
    assert compare_trials(base, fingerprint(RUN, [other, _record(1)])) == [
        "trial 0: same outcomes and scores, other fields of the record differ"]


def test_missing_and_extra_trials_and_attempts_are_named():
    base = fingerprint(RUN, [_record(0), _record(1)])
    run = fingerprint(RUN, [_record(0, scores=(0.7,), reasons=(None,)), _record(2)])
    assert compare_trials(base, run) == ["trial 0: attempt 2: gone (was obj1: success (score 0.600000))",
                                         "trial 1: only in the baseline", "trial 2: only in the run"]


def test_canonical_digest_ignores_key_order_only():
    a = {"a": 1, "b": [1.5, None]}
    assert canonical_sha256(a) == canonical_sha256(dict(reversed(list(a.items()))))
    b = copy.deepcopy(a)
    b["b"][0] = 1.5000000000000002
    assert canonical_sha256(a) != canonical_sha256(b)
