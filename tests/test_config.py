"""Task files: the shipped tasks load, and every kind of bad file is a ConfigError naming the file and the problem."""

import json
import re
from dataclasses import replace
from pathlib import Path

import pytest

from kgn_bench.config import (
    ConfigError,
    ResourceConfig,
    TaskConfig,
    apply_override,
    load_task,
    task_from_dict,
    validate,
)
from kgn_bench.shapes import PRIMITIVES

TASKS = Path(__file__).resolve().parents[1] / "tasks"
HEAD = '[task]\nname = "t"\nprotocol = "single_object"\n'


def test_single_object_task():
    t = load_task(TASKS / "single_object.toml")
    assert (t.name, t.protocol, t.seed, t.trials) == ("single_object", "single_object", 0, 20)
    assert t.objects == ("cuboid", "cylinder", "ring", "stick", "sphere", "semi_sphere")
    assert t.n_trials == 120  # trials per object × objects
    assert t.camera.distance == 0.8 and t.camera.elevation_deg == 60.0 and t.camera.azimuth_deg == 90.0
    assert isinstance(t.camera.distance, float)
    assert t.selector.score == "confidence_minus_error" and t.selector.reprojection_weight == 0.0
    assert t.execution.max_consecutive_failures == 3


def test_multi_object_task():
    t = load_task(TASKS / "multi_object.toml")
    assert (t.name, t.protocol, t.trials, t.objects_per_scene) == ("multi_object", "multi_object", 30, 5)
    assert set(t.objects) == set(PRIMITIVES)
    assert t.n_trials == 30  # scenes, not scenes × objects


def test_ci_oracle_task_and_overrides():
    t = load_task(TASKS / "ci_oracle.toml")
    assert (t.name, t.protocol, t.trials, t.n_trials) == ("ci_oracle", "single_object", 1, 6)
    o = t.with_overrides(trials=3, seed=7)
    assert (o.trials, o.seed, o.n_trials) == (3, 7, 18)
    assert t.with_overrides() == t
    d = t.to_dict()
    assert d["name"] == "ci_oracle" and d["camera"]["distance"] == 0.8 and list(d["objects"]) == list(t.objects)


def test_defaults_fill_optional_sections(tmp_path):
    p = tmp_path / "min.toml"
    p.write_text('[task]\nname = "m"\nprotocol = "multi_object"\n[camera]\ndistance = 1\n')
    t = load_task(p)
    assert t == TaskConfig(name="m", protocol="multi_object", camera=t.camera)
    assert t.camera.distance == 1.0 and isinstance(t.camera.distance, float)  # ints accepted for floats
    assert t.objects == tuple(PRIMITIVES) and t.trials == 10 and t.n_trials == 10


@pytest.mark.parametrize(
    "body, fragment",
    [
        ("[task\nname = 1\n", "not valid TOML"),
        (HEAD + "[robot]\nspeed = 1\n", "unknown section [robot]"),
        (HEAD + "[camera]\nzoom = 2.0\n", "unknown key 'zoom'"),
        (HEAD + "colour = 'red'\n", "[task] unknown key 'colour'"),
        (HEAD + "[objects]\nset = ['cuboid']\ncount = 3\n", "[objects] unknown key 'count'"),
        (HEAD + "[camera]\ndistance = 'far'\n", "distance must be a number or a list of 2 numbers [lo, hi], got 'far'"),
        (HEAD + "[execution]\nmax_attempts_per_object = 2.5\n", "max_attempts_per_object must be int"),
        (HEAD + "[selector]\nmax_candidates = true\n", "max_candidates must be int"),
        ('[task]\nname = "t"\nprotocol = "single_object"\ntrials = "ten"\n', "trials must be int"),
        (HEAD + "[objects]\nset = ['cuboid', 'teapot']\n", "unknown object 'teapot'"),
        (HEAD + "[objects]\nset = []\n", "non-empty list"),
        (HEAD + "[objects]\nper_scene = 0\n", "per_scene must be a positive integer"),
        ('[task]\nname = "t"\nprotocol = "clearance"\n', "protocol must be one of single_object, multi_object"),
        ('[task]\nprotocol = "single_object"\n', "[task] needs 'name'"),
        ('[task]\nname = "t"\n', "[task] needs 'protocol'"),
        ('[task]\nname = "t"\nprotocol = "single_object"\ntrials = 0\n', "trials must be ≥ 1"),
        (HEAD + "[selector]\nscore = 'c_times_re'\n", "selector.score must be one of"),
        (HEAD + "[camera]\ndistance = 5.0\n", "camera.distance must lie in [0.3, 2] m"),
        (HEAD + "[camera]\nelevation_deg = 5\n", "camera.elevation_deg must lie in [10, 90]"),
        (HEAD + "[execution]\nmax_consecutive_failures = 0\n", "max_consecutive_failures must be ≥ 1"),
        (HEAD + "[resources]\nnum_cpus = 0\n", "num_cpus must be > 0, got 0.0"),
        (HEAD + "[resources]\nnum_gpus = -1\n", "num_gpus must be ≥ 0, got -1.0"),
        (HEAD + "[resources]\nmemory = 4\n", "[resources]: unknown key 'memory' (known: num_cpus, num_gpus)"),
        (HEAD.replace('name = "t"', 'name = "../../escaped/x"'), "task name '../../escaped/x' must be letters"),
        (HEAD.replace('name = "t"', 'name = "/abs/x"'), "task name '/abs/x' must be letters"),
        (HEAD.replace('name = "t"', 'name = ".hidden"'), "not starting with a dot"),
        ('[task]\nname = "t"\nprotocol = "single_object"\n[objects]\nset = ["/etc/passwd"]\n',
         "object '/etc/passwd' is not an object name"),
    ],
    ids=[
        "malformed",
        "unknown_section",
        "unknown_camera_key",
        "unknown_task_key",
        "unknown_objects_key",
        "wrong_type_float",
        "wrong_type_int",
        "bool_for_int",
        "wrong_type_trials",
        "unknown_object",
        "empty_set",
        "per_scene_0",
        "bad_protocol",
        "missing_name",
        "missing_protocol",
        "trials_0",
        "bad_score",
        "distance_range",
        "elevation_range",
        "max_failures_0",
        "num_cpus_0",
        "num_gpus_negative",
        "unknown_resources_key",
        "name_with_dots",
        "name_absolute",
        "name_hidden",
        "object_path",
    ],
)
def test_bad_task_files_name_the_file_and_the_problem(tmp_path, body, fragment):
    p = tmp_path / "bad.toml"
    p.write_text(body)
    with pytest.raises(ConfigError) as e:
        load_task(p)
    msg = str(e.value)
    assert str(p) in msg and fragment in msg
    assert "\n" not in msg


@pytest.mark.parametrize(
    "body, fragment",
    [
        pytest.param(
            HEAD + "[camera]\ntarget = ['a', 0, 0]\n",
            "target",
        ),
        pytest.param(
            HEAD + "[camera]\ntarget = [0.1, 0.2]\n",
            "target",
        ),
        pytest.param(
            HEAD + "seed = -1\n",
            "seed",
        ),
        pytest.param(
            HEAD + "[objects]\nper_scene = true\n",
            "per_scene",
        ),
        pytest.param(
            HEAD + "[selector]\npoint_stride = 0\n",
            "point_stride",
        ),
        pytest.param(
            "camera = 1\n" + HEAD,
            "camera",
        ),
        pytest.param("task = 1\n", "task"),
    ],
    ids=[
        "target_item_type",
        "target_length",
        "negative_seed",
        "per_scene_bool",
        "point_stride_0",
        "section_not_table",
        "task_not_table",
    ],
)
def test_loader_gaps(tmp_path, body, fragment):
    p = tmp_path / "bad.toml"
    p.write_text(body)
    with pytest.raises(ConfigError) as e:
        load_task(p)
    assert str(p) in str(e.value) and fragment in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="no such task file"):
        load_task(tmp_path / "nope.toml")


def test_validate_checks_overrides():
    t = load_task(TASKS / "ci_oracle.toml")
    validate(t.with_overrides(trials=2), "cli")
    with pytest.raises(ConfigError, match=r"^cli: trials must be ≥ 1, got 0$"):
        validate(t.with_overrides(trials=0), "cli")


def test_apply_override_sets_one_typed_value_and_validates_it():
    from kgn_bench.config import apply_override

    t = load_task(TASKS / "single_object.toml")
    assert apply_override(t, "camera.depth_noise", "1.5").camera.depth_noise == 1.5
    assert apply_override(t, "selector.reprojection_weight", "0").selector.reprojection_weight == 0.0
    assert apply_override(t, "selector.score", "paper_literal").selector.score == "paper_literal"
    assert apply_override(t, "camera.target", "0.1, 0, 0").camera.target == (0.1, 0.0, 0.0)
    assert apply_override(t, "execution.max_consecutive_failures", "2").execution.max_consecutive_failures == 2
    assert t.camera.depth_noise == 0.0  # the original is untouched
    for key, value, fragment in [
        ("camera.depth_noise", "loud", "cannot read 'loud' as float"),
        ("camera.depth_noise", "-1", "camera.depth_noise must be in"),
        ("camera.zoom", "1", "unknown setting 'camera.zoom'"),
        ("robot.speed", "1", "section one of camera, selector, execution"),
        ("selector.score", "best", "selector.score must be one of"),
        ("execution.max_consecutive_failures", "1.5", "must be int"),
        ("camera.noise_model", "kinect", "camera.noise_model must be one of d435, dex"),
        ("camera.intrinsics", "zed", "camera.intrinsics must be one of realsense, giga"),
    ]:
        with pytest.raises(ConfigError, match=re.escape(fragment)):
            apply_override(t, key, value)


def test_the_dex_model_is_on_or_off_and_giga_names_its_camera():
    from kgn_bench.config import apply_override

    t = apply_override(load_task(TASKS / "pile.toml"), "camera.noise_model", "dex")
    assert apply_override(t, "camera.depth_noise", "1").camera.depth_noise == 1.0
    with pytest.raises(ConfigError, match="dex noise model is on or off"):
        apply_override(t, "camera.depth_noise", "0.5")
    assert apply_override(t, "camera.intrinsics", "giga").camera.intrinsics == "giga"


def test_camera_ranges_parse_draw_per_trial_and_validate(tmp_path):
    import numpy as np

    from kgn_bench.bench.trial import camera_coordinates, camera_pose

    p = tmp_path / "ranged.toml"
    p.write_text(HEAD + "[camera]\ndistance = [0.6, 1.0]\nelevation_deg = [30, 90]\nazimuth_deg = [-45, 45]\n")
    t = load_task(p)
    assert t.camera.distance == (0.6, 1.0) and not t.camera.fixed and load_task("single_object").camera.fixed
    coords = np.array([camera_coordinates(t, i) for i in range(40)])
    assert np.all((coords >= [0.6, 30, -45]) & (coords <= [1.0, 90, 45])) and len(np.unique(coords[:, 0])) == 40
    np.testing.assert_array_equal(camera_pose(t, 3), camera_pose(t, 3))  # seeded per trial
    assert not np.allclose(camera_pose(t, 3), camera_pose(t, 4))
    assert camera_coordinates(replace(t, seed=1), 3) != camera_coordinates(t, 3)
    eye = camera_pose(t, 5)[:3, 3]
    assert np.linalg.norm(eye) == pytest.approx(camera_coordinates(t, 5)[0])
    for body, fragment in (("elevation_deg = [90, 30]", "camera.elevation_deg must lie in [10, 90]"),
                           ("distance = [0.1, 1.0]", "camera.distance must lie in [0.3, 2]"),
                           ("distance = [0.6, 0.8, 1.0]", "distance must be a number or a list of 2 numbers")):
        p.write_text(HEAD + f"[camera]\n{body}\n")
        with pytest.raises(ConfigError, match=re.escape(fragment)):
            load_task(p)


def test_selector_mode_and_the_clutter_protocols():
    from kgn_bench.config import RAW_SELECTOR, apply_override

    for name in ("pile", "packed"):
        t = load_task(name)
        assert t.protocol == name and t.clearance and t.selector.mode == "raw"
        assert t.execution.max_consecutive_failures == 2
    raw = load_task("single_object").selector
    assert raw.mode == "assisted" and raw.effective() == raw
    eff = apply_override(load_task("single_object"), "selector.mode", "raw").selector.effective()
    assert all(getattr(eff, k) == v for k, v in RAW_SELECTOR.items())
    with pytest.raises(ConfigError, match=r"selector\.mode must be one of assisted, raw"):
        apply_override(load_task("single_object"), "selector.mode", "blind")


def test_resources_are_read_from_the_task_file(tmp_path):
    p = tmp_path / "r.toml"
    p.write_text(HEAD + "[resources]\nnum_cpus = 2\nnum_gpus = 0.25\n")
    t = load_task(p)
    assert t.resources == ResourceConfig(num_cpus=2.0, num_gpus=0.25)
    assert load_task(TASKS / "single_object.toml").resources == ResourceConfig(num_cpus=1.0, num_gpus=0.0)


def test_a_runs_stored_config_reads_back_as_the_task():
    task = load_task(TASKS / "pile.toml")
    task = replace(task, camera=replace(task.camera, elevation_deg=(30.0, 90.0)))
    task = apply_override(task, "selector.mode", "raw")
    stored = json.loads(json.dumps(task.to_dict()))  # as run.json holds it: tuples become lists
    del stored["resources"]
    assert task_from_dict(stored, "run.json config") == task
    with pytest.raises(ConfigError, match=re.escape("run.json config: unknown key 'colour'")):
        task_from_dict({**stored, "colour": 1}, "run.json config")
    with pytest.raises(ConfigError, match=re.escape("run.json config camera: unknown key 'fov'")):
        task_from_dict({**stored, "camera": {"fov": 60}}, "run.json config")
    with pytest.raises(ConfigError, match="trials must be int"):
        task_from_dict({**stored, "trials": "many"}, "run.json config")
