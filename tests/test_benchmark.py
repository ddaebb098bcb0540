"""Benchmark plans: validation with one-line errors, and a tiny real plan run end to end into a report."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from kgn_bench.bench.benchmark import load_plan
from kgn_bench.cli import main
from kgn_bench.config import ConfigError

TASKS = Path(__file__).resolve().parents[1] / "tasks"


def test_shipped_plan_loads_and_can_be_restricted():
    plan = load_plan(TASKS / "benchmark.toml")
    assert "kgnv2" in plan.detectors and "oracle" in plan.detectors
    assert [t.name for t in plan.tasks][:1] == ["single_object"]
    # vgn (an 8 cm hand inside GIGA's cube) runs in GIGA's rounds only; every other detector everywhere
    assert "vgn" in plan.detectors_of("giga_pile") and "vgn" in plan.detectors_of("giga_packed")
    assert "vgn" not in plan.detectors_of("pile") and "antipodal" in plan.detectors_of("giga_pile")
    # the main job's ten tasks (Makefile MAIN_TASKS) are the plan's tasks before GIGA's rounds
    makefile = (TASKS.parent / "Makefile").read_text()
    main_tasks = makefile.split("MAIN_TASKS =")[1].split("\nbenchmark:")[0].replace("\\", " ").split()
    assert [t.replace("@", "_") for t in main_tasks] == [t.name for t in plan.tasks if not t.name.startswith("giga_")]
    only = load_plan(TASKS / "benchmark.toml", tasks=["multi_object"], detectors=["kgnv2"])
    assert [t.name for t in only.tasks] == ["multi_object"] and only.detectors == ("kgnv2",)
    # the viewpoint study: camera sweeps of single_object, kept only when that task is in the plan
    assert [v.name for v in plan.viewpoints] == ["elevation_az0", "azimuth_el45", "distance"]
    elevation = plan.viewpoints[0]
    assert elevation.values == ("35", "45", "60", "75", "90") and elevation.task.n_trials == 18
    assert (elevation.task.camera.azimuth_deg, elevation.task.camera.distance) == (0.0, 1.0)
    assert only.viewpoints == ()
    assert len(load_plan(TASKS / "benchmark.toml", tasks=["single_object"]).viewpoints) == 3


VIEW = "\n[[benchmark.viewpoints]]\ntask = 'ci_oracle'\n"


PLAN = "[benchmark]\ntasks = ['ci_oracle']\ndetectors = ['oracle']"


@pytest.mark.parametrize("body, fragment", [
    ("[benchmark]\ntasks = []\ndetectors = ['oracle']", "tasks must be a non-empty list"),
    ("[benchmark]\ntasks = ['ci_oracle']\ndetectors = ['telepathy']", "unknown detector 'telepathy'"),
    ("[benchmark]\ntasks = ['nope']\ndetectors = ['oracle']", "no such task file"),
    ("[benchmark]\ntasks = ['ci_oracle']\ndetectors = ['oracle']\nspeed = 2", "unknown key 'speed'"),
    ("[bench]\ntasks = ['ci_oracle']", "exactly one [benchmark] table"),
    (PLAN + "\nseeds = [1, 1]", "seeds must be a list of distinct integers"),
    (PLAN + "\nseeds = [-1]", "seeds must be a list of distinct integers"),
    (PLAN + VIEW + "param = 'selector.level_deg'\nvalues = [0]", "param must be a camera setting"),
    (PLAN + VIEW + "param = 'camera.elevation_deg'\nvalues = []", "values must be a non-empty list"),
    (PLAN + VIEW + "param = 'camera.elevation_deg'\nvalues = [45]\nspin = 1", "unknown key 'spin'"),
    (PLAN + VIEW + "param = 'camera.elevation_deg'\nvalues = [45]\ntrials = 0", "trials must be a positive"),
    (PLAN + VIEW + "param = 'camera.roll_deg'\nvalues = [45]", "unknown setting 'camera.roll_deg'"),
    (PLAN + VIEW + "param = 'camera.elevation_deg'\nvalues = [45]" + VIEW + "param = 'camera.elevation_deg'\n"
     "values = [60]", "the same name"),
    (PLAN + "\nonly = {random = ['ci_oracle']}", "only names detector 'random', which is not in detectors"),
    (PLAN + "\nonly = {oracle = ['pile']}", "only.oracle names task 'pile', which is not in tasks"),
    (PLAN + "\nonly = {oracle = []}", "only.oracle must be a non-empty list"),
    (PLAN + "\nonly = ['oracle']", "only must be a table"),
])
def test_bad_plans_name_the_problem(tmp_path, body, fragment):
    plan = tmp_path / "plan.toml"
    plan.write_text(body)
    (tmp_path / "ci_oracle.toml").write_text((TASKS / "ci_oracle.toml").read_text())
    with pytest.raises(ConfigError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
        load_plan(plan)


def test_tiny_plan_runs_every_pair_and_reports(tmp_path, capsys):
    task = (TASKS / "ci_oracle.toml").read_text()
    task = task.replace('name = "ci_oracle"', 'name = "tiny"')
    (tmp_path / "tiny.toml").write_text(task.split("[objects]")[0] + '[objects]\nset = ["sphere", "cuboid"]\n')
    plan = tmp_path / "plan.toml"
    plan.write_text("[benchmark]\ntasks = ['tiny']\ndetectors = ['random', 'oracle']\n")
    rc = main(["benchmark", str(plan), "--runs", str(tmp_path / "runs"), "--workers", "1", "--quiet",
               "--set", "selector.palm_margin=0.005"])
    assert rc == 0
    for det in ("random", "oracle"):
        assert (tmp_path / "runs" / "tiny" / det / "summary.json").is_file()
        run = json.loads((tmp_path / "runs" / "tiny" / det / "run.json").read_text())
        assert run["config"]["selector"]["palm_margin"] == 0.005  # --set reached every task
    out = capsys.readouterr().out
    assert "| random |" in out and "| oracle |" in out
    assert (tmp_path / "runs" / "benchmark.png").is_file()
    # the report command rebuilds it from the folder of runs
    assert main(["report", str(tmp_path / "runs"), "--out", str(tmp_path / "rep")]) == 0
    assert (tmp_path / "rep" / "benchmark.md").read_text().count("| oracle |") == 3  # table, failures, per object


def test_a_plans_viewpoint_study_runs_for_every_detector_and_is_reported(tmp_path, capsys):
    task = (TASKS / "ci_oracle.toml").read_text().replace('name = "ci_oracle"', 'name = "tiny"')
    (tmp_path / "tiny.toml").write_text(task.split("[objects]")[0] + '[objects]\nset = ["sphere"]\n')
    plan = tmp_path / "plan.toml"
    plan.write_text("[benchmark]\ntasks = ['tiny']\ndetectors = ['random', 'oracle']\n"
                    "[[benchmark.viewpoints]]\ntask = 'tiny'\nparam = 'camera.elevation_deg'\nvalues = [45, 90]\n"
                    "set = {'camera.azimuth_deg' = 0}\n")
    runs = tmp_path / "runs"
    assert main(["benchmark", str(plan), "--runs", str(runs), "--workers", "1", "--quiet", "--no-viewpoints"]) == 0
    assert not (runs / "viewpoints").exists()
    capsys.readouterr()
    assert main(["benchmark", str(plan), "--runs", str(runs), "--workers", "1", "--quiet"]) == 0
    study = runs / "viewpoints" / "tiny_elevation_deg"
    for det in ("random", "oracle"):
        for value in ("45", "90"):
            run = json.loads((study / det / f"camera.elevation_deg={value}" / "run.json").read_text())
            assert run["config"]["camera"]["elevation_deg"] == float(value)
            assert run["config"]["camera"]["azimuth_deg"] == 0.0
    report = (runs / "benchmark.md").read_text()
    section = report.split("## Viewpoint study")[1].split("## Failure reasons")[0]
    assert "### tiny_elevation_deg: tiny, camera.elevation_deg (distance 0.8 m, azimuth 0°)" in section
    assert "| camera.elevation_deg | random | oracle |" in section
    assert section.count("\n| 45 | ") == 1 and section.count("\n| 90 | ") == 1
    assert (runs / "viewpoints_tiny_elevation_deg.png").read_bytes() == (study / "sweep.png").read_bytes()
    payload = json.loads((runs / "benchmark.json").read_text())["viewpoints"]["tiny_elevation_deg"]
    assert payload["values"] == ["45", "90"] and set(payload["detectors"]) == {"random", "oracle"}


def test_a_plan_with_seeds_runs_each_seed_and_reports_one_cell(tmp_path, capsys):
    task = (TASKS / "ci_oracle.toml").read_text().replace('name = "ci_oracle"', 'name = "tiny"')
    task = task.split("[objects]")[0] + '[objects]\nset = ["sphere", "cuboid"]\n'
    (tmp_path / "tiny.toml").write_text(task.replace("trials = ", "trials = 1 #"))
    plan = tmp_path / "plan.toml"
    plan.write_text("[benchmark]\ntasks = ['tiny']\ndetectors = ['oracle']\nseeds = [3, 4]\n")
    assert load_plan(plan).seeds == (3, 4)
    assert main(["benchmark", str(plan), "--runs", str(tmp_path / "runs"), "--workers", "1", "--quiet"]) == 0
    for seed in (3, 4):
        run = json.loads((tmp_path / "runs" / "tiny" / "oracle" / f"seed{seed}" / "run.json").read_text())
        assert run["config"]["seed"] == seed
    out = capsys.readouterr().out
    assert out.count("over 2 seeds") >= 1


def test_benchmark_rejects_a_bad_setting_before_running(tmp_path, capsys):
    rc = main(["benchmark", str(TASKS / "benchmark.toml"), "--runs", str(tmp_path / "runs"), "--quiet",
               "--set", "selector.palm_width=1"])
    assert rc != 0
    assert "unknown setting 'selector.palm_width'" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


def test_a_plan_keeps_a_detector_to_its_tasks(tmp_path, capsys):
    task = (TASKS / "ci_oracle.toml").read_text()
    for name, obj in (("tiny", "sphere"), ("other", "cuboid")):
        body = task.replace('name = "ci_oracle"', f'name = "{name}"').replace("trials = ", "trials = 1 #")
        (tmp_path / f"{name}.toml").write_text(body.split("[objects]")[0] + f'[objects]\nset = ["{obj}"]\n')
    plan = tmp_path / "plan.toml"
    plan.write_text("[benchmark]\ntasks = ['tiny', 'other@raw']\ndetectors = ['random', 'oracle']\n"
                    "only = {random = ['other@raw']}\n"
                    "[[benchmark.viewpoints]]\ntask = 'tiny'\nparam = 'camera.elevation_deg'\nvalues = [90]\n")
    loaded = load_plan(plan)
    assert loaded.only == (("random", ("other_raw",)),)
    assert loaded.detectors_of("tiny") == ("oracle",) and loaded.detectors_of("other_raw") == ("random", "oracle")
    runs = tmp_path / "runs"
    assert main(["benchmark", str(plan), "--runs", str(runs), "--workers", "1", "--quiet"]) == 0
    assert sorted(p.name for p in (runs / "tiny").iterdir()) == ["oracle"]
    assert sorted(p.name for p in (runs / "other_raw").iterdir()) == ["oracle", "random"]
    assert sorted(p.name for p in (runs / "viewpoints" / "tiny_elevation_deg").iterdir()
                  if p.is_dir()) == ["oracle"]
    table = (runs / "benchmark.md").read_text().split("| random |")[1].split("\n")[0]
    assert "—" in table  # no run of random on tiny: its cell is empty, not a rate
