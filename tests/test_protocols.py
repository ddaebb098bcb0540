"""The protocol registry: one description per protocol that config, the trial loop, the statistics and the
report read, and a new protocol added by one registry entry."""

from dataclasses import replace
from pathlib import Path

import pytest

from kgn_bench import config, protocols
from kgn_bench.bench.report import HARD_PROTOCOLS
from kgn_bench.bench.stats import per_object_meaning, summarise
from kgn_bench.bench.trial import ARRANGEMENTS, run_trial
from kgn_bench.config import ConfigError, load_task
from kgn_bench.detectors import make_detector
from kgn_bench.protocols import PROTOCOLS, Protocol, protocol
from kgn_bench.sim.control import IK

TASKS = Path(__file__).resolve().parents[1] / "tasks"


def test_the_registry_gives_the_protocols_and_their_groups():
    giga = ("giga_pile", "giga_packed")
    assert list(PROTOCOLS) == ["single_object", "multi_object", "pile", "packed", *giga] == list(config.PROTOCOLS)
    assert protocols.CLEARANCE_PROTOCOLS == config.CLEARANCE_PROTOCOLS == ("multi_object", "pile", "packed", *giga)
    assert protocols.CLUTTER_PROTOCOLS == config.CLUTTER_PROTOCOLS == ("pile", "packed", *giga)
    assert HARD_PROTOCOLS == ("pile", "packed")
    assert all(p.arrangement in ARRANGEMENTS for p in PROTOCOLS.values())
    assert [name for name, p in PROTOCOLS.items() if p.pile_box] == ["pile", "giga_pile"]
    assert [name for name, p in PROTOCOLS.items() if p.report_tier == "giga"] == list(giga)
    assert all(PROTOCOLS[n].draws_with_replacement and PROTOCOLS[n].workspace_cube for n in giga)


def test_what_each_protocol_means():
    single, multi, pile = PROTOCOLS["single_object"], PROTOCOLS["multi_object"], PROTOCOLS["pile"]
    assert single.one_object and not single.park_between_attempts and not single.clearance
    assert (single.per_object_meaning, multi.per_object_meaning) == ("success", "put in the bin")
    assert multi.park_between_attempts and not multi.gsr_executed_only and multi.report_tier == "main"
    assert pile.ends_when_nothing_executed and pile.gsr_executed_only and pile.counts_fallen
    assert pile.report_tier == "hard"
    # a summary without a protocol reads as the statistics always read one: per object put in the bin
    assert not protocol(None).clearance and not protocol(None).clutter and per_object_meaning(None) == "put in the bin"


def test_the_task_reads_its_protocol():
    single = load_task(TASKS / "ci_oracle.toml")
    assert single.spec is PROTOCOLS["single_object"] and single.n_trials == single.trials * len(single.objects)
    multi = load_task(TASKS / "multi_object.toml")
    assert multi.clearance and multi.n_trials == multi.trials


def test_a_new_protocol_is_one_registry_entry(monkeypatch, tmp_path):
    """A clutter round on objects spread on the table: config accepts it, the trial ends and counts as a clutter
    round, the summary counts it as one."""
    monkeypatch.setitem(PROTOCOLS, "spread_clutter", Protocol("spread_clutter", clutter=True))
    p = tmp_path / "t.toml"
    p.write_text('[task]\nname = "t"\nprotocol = "spread_clutter"\ntrials = 1\n[objects]\nper_scene = 2\n')
    task = load_task(p)
    assert task.clearance and task.n_trials == 1
    record = run_trial(task, 0, make_detector("oracle"), IK())
    assert record.protocol == "spread_clutter" and record.fell_at_setup is not None and record.fallen is not None
    assert list(record.to_json())[-3:] == ["fell_at_setup", "fallen", "timing"]
    summary = summarise([record], {"task": "t", "protocol": "spread_clutter"})
    assert {"success", "clear", "scenes_cleared"} <= set(summary["rates"]) and "fallen" in summary
    monkeypatch.delitem(PROTOCOLS, "spread_clutter")
    with pytest.raises(ConfigError, match="protocol must be one of single_object, multi_object, pile, packed"):
        load_task(p)


def test_an_arrangement_is_what_builds_the_scene(monkeypatch):
    """The trial builds its scene with its protocol's arrangement function and nothing else."""
    called = []
    monkeypatch.setitem(ARRANGEMENTS, "pile", lambda scene, rng: called.append(len(scene.objects)))
    task = replace(load_task(TASKS / "pile.toml"), objects_per_scene=2, trials=1)
    record = run_trial(task, 0, make_detector("random"), IK())
    assert called == [2] and record.protocol == "pile"
