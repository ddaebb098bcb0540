"""The dataset generator end to end: files, determinism across workers, resume, refusals, and
consistency between annotations, renders and masks."""

import os
import shutil

import numpy as np
import pytest

from kgn_bench.data.format import DatasetError, SceneAnnotation, read_split, read_view, scene_dir
from kgn_bench.data.generate import GenerateConfig, generate_dataset, relabel_grasps
from kgn_bench.geometry import invert_pose, project, transform_points
from kgn_bench.kernels import PORTABLE
from kgn_bench.shapes import EVAL_DENSITY, TRAIN_DENSITY


def _annotations(root, n):
    return [(scene_dir(root, i) / "scene.json").read_bytes() for i in range(n)]


def test_layout_and_split(tiny_dataset):
    root, config = tiny_dataset
    for i in range(config.scenes):
        names = sorted(p.name for p in scene_dir(root, i).iterdir())
        assert names == sorted(["scene.json"] + [f"{k}_{v}.png" for k in ("rgb", "depth", "mask") for v in range(2)])
    train, test = read_split(root, "train"), read_split(root, "test")
    assert sorted(train + test) == list(range(config.scenes)) and len(test) == 1
    big = GenerateConfig(scenes=1000).split()
    assert len(big[1]) == 200 and not set(big[0]) & set(big[1])
    for bad in (dict(scenes=0), dict(views=0), dict(seed=-1)):
        with pytest.raises(ValueError, match="scenes and views must be"):
            GenerateConfig(**bad)


def test_same_seed_same_files_whatever_the_worker_count(tiny_dataset, tmp_path):
    root, config = tiny_dataset
    other = tmp_path / "w2"
    generate_dataset(config, other, workers=2, progress=False)
    assert _annotations(root, 3) == _annotations(other, 3)
    for i in range(3):
        a, b = read_view(scene_dir(root, i), 1), read_view(scene_dir(other, i), 1)
        np.testing.assert_array_equal(a.depth, b.depth)
        np.testing.assert_array_equal(a.mask, b.mask)


def test_resume_regenerates_only_missing_scenes(tiny_dataset, tmp_path):
    root, config = tiny_dataset
    copy = tmp_path / "copy"
    shutil.copytree(root, copy)
    shutil.rmtree(scene_dir(copy, 1))
    (copy / "scenes" / ".tmp-00001-999").mkdir()  # a crashed write
    (copy / "test.txt").unlink()
    kept = os.stat(scene_dir(copy, 0) / "scene.json").st_mtime_ns
    stats = generate_dataset(config, copy, workers=1, progress=False)
    assert stats.scenes == 1
    assert os.stat(scene_dir(copy, 0) / "scene.json").st_mtime_ns == kept
    assert _annotations(copy, 3) == _annotations(root, 3)
    assert not list((copy / "scenes").glob(".tmp-*"))
    assert (copy / "test.txt").read_text() == (root / "test.txt").read_text()


def test_refuses_foreign_or_different_folders(tiny_dataset, tmp_path):
    root, config = tiny_dataset
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("keep me")
    with pytest.raises(DatasetError, match="not empty"):
        generate_dataset(config, foreign, progress=False)
    other = GenerateConfig(mode="multi", scenes=4, views=2, seed=7)
    with pytest.raises(DatasetError, match="other settings \\(scenes\\)"):
        generate_dataset(other, root, progress=False)
    small = GenerateConfig(mode="single", scenes=1, views=1, seed=3)
    generate_dataset(small, foreign, overwrite=True, progress=False)
    assert (foreign / "notes.txt").read_text() == "keep me"
    assert len(SceneAnnotation.load(scene_dir(foreign, 0) / "scene.json").objects) == 1


def test_the_manifest_names_the_kernel_set_and_a_resume_under_another_is_refused(tiny_dataset, monkeypatch):
    """Scenes settle differently in their last bits under native kernels, so a dataset begun under the
    portable set is not finished under another one."""
    root, config = tiny_dataset
    assert config.manifest()["kernels"] == PORTABLE  # the test session runs under the portable set
    monkeypatch.setenv("KGN_BENCH_KERNELS", "native")
    assert config.manifest()["kernels"].startswith("native (")
    with pytest.raises(DatasetError, match="other settings \\(kernels\\)"):
        generate_dataset(config, root, progress=False)


def test_relabelling_reproduces_stored_labels_and_densifies(tiny_dataset):
    root, _ = tiny_dataset
    ann = SceneAnnotation.load(scene_dir(root, 2) / "scene.json")
    again = relabel_grasps(ann, TRAIN_DENSITY)
    for obj, g in zip(ann.objects, again):
        np.testing.assert_allclose(g.poses, obj.grasps.poses, atol=1e-12)
        np.testing.assert_array_equal(g.collides, obj.grasps.collides)
    dense = relabel_grasps(ann, EVAL_DENSITY)
    assert sum(len(g) for g in dense) == 120 + 360 + 60 + 300 + 60 + 30


def test_grasps_project_onto_their_own_objects(tiny_dataset):
    """Collision-free grasp origins, projected with K, land on (or right beside) their object's mask."""
    root, config = tiny_dataset
    hits = total = 0
    for i in range(config.scenes):
        folder = scene_dir(root, i)
        ann = SceneAnnotation.load(folder / "scene.json")
        for v in range(config.views):
            view = read_view(folder, v)
            T_cw = invert_pose(ann.camera_poses[v])
            for k, obj in enumerate(ann.objects):
                free = obj.grasps.free()
                if not len(free):
                    continue
                uv = np.rint(project(transform_points(T_cw, free.poses[:, :3, 3]), ann.intrinsics.K)).astype(int)
                ys, xs = np.nonzero(view.mask == k + 1)
                if len(xs) == 0:
                    continue
                d = np.hypot(uv[:, :1] - xs[None], uv[:, 1:] - ys[None]).min(axis=1)
                hits += int(np.sum(d <= 3))
                total += len(d)
    assert total > 50
    assert hits / total > 0.9, (hits, total)


def test_physics_failure_names_the_scene_and_leaves_no_partial_files(tmp_path, monkeypatch, capsys):
    from kgn_bench import cli
    from kgn_bench.data import generate as gen
    from kgn_bench.sim.scene import PhysicsError

    def explode(scene, config):
        raise PhysicsError("object 0 (sphere) left the table")

    monkeypatch.setattr(gen, "settle", explode)
    with pytest.raises(PhysicsError, match=r"scene 0: object 0 .*after 5 attempts"):
        generate_dataset(GenerateConfig(mode="single", scenes=1, views=1), tmp_path / "a", progress=False)
    assert not any((tmp_path / "a" / "scenes").iterdir())
    rc = cli.main(["data", "generate", "--mode", "single", "--scenes", "1", "--out", str(tmp_path / "b"), "--quiet"])
    assert rc == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "left the table" in err and "resume" in err


def test_scenes_of_imported_objects(object_library, tmp_path):
    """``objects=`` draws scenes from imported objects: their verified grasps are the labels, relabelling
    reproduces them, and a name that is neither built in nor imported is refused."""
    config = GenerateConfig(mode="multi", scenes=2, views=1, seed=0, objects=("test_block",))
    generate_dataset(config, tmp_path / "d", progress=False)
    ann = SceneAnnotation.load(scene_dir(tmp_path / "d", 0) / "scene.json")
    assert [o.type for o in ann.objects] == ["test_block"] and len(ann.objects[0].grasps) >= 8
    again = relabel_grasps(ann, TRAIN_DENSITY)
    np.testing.assert_allclose(again[0].poses, ann.objects[0].grasps.poses, atol=1e-12)
    with pytest.raises(ValueError, match="unknown object 'no_such_thing'"):
        GenerateConfig(objects=("no_such_thing",))


def test_random_appearance_and_depth_noise_change_only_what_they_are_for(tmp_path):
    """Textures change the RGB only and depth noise the depth only: the scenes, cameras and labels stay those
    of the plain dataset (separate random streams), and the manifest names each setting only when it is on."""
    from kgn_bench.data.generate import generate_scene

    plain = GenerateConfig(mode="multi", scenes=1, views=1, seed=5)
    looks = GenerateConfig(mode="multi", scenes=1, views=1, seed=5, appearance="random")
    noisy = GenerateConfig(mode="multi", scenes=1, views=1, seed=5, depth_noise=1.0)
    a, b, c = (generate_scene(cfg, 0) for cfg in (plain, looks, noisy))
    assert a.annotation.to_json() == b.annotation.to_json() == c.annotation.to_json()
    va, vb, vc = a.views[0], b.views[0], c.views[0]
    np.testing.assert_array_equal(vb.depth, va.depth)
    np.testing.assert_array_equal(vb.mask, va.mask)
    assert np.abs(vb.rgb.astype(int) - va.rgb.astype(int)).mean() > 5
    np.testing.assert_array_equal(vc.rgb, va.rgb)
    both = (va.depth > 0) & (vc.depth > 0)
    assert 0 < np.abs(vc.depth[both] - va.depth[both]).mean() < 0.01 and (vc.depth == 0).sum() > (va.depth == 0).sum()
    assert "appearance" not in plain.manifest() and "depth_noise" not in plain.manifest()
    assert looks.manifest()["appearance"] == "random" and noisy.manifest()["depth_noise"] == 1.0
    with pytest.raises(ValueError, match="appearance must be one of"):
        GenerateConfig(appearance="marble")


def test_groups_are_drawn_equally_often_and_enter_the_manifest_only_when_set():
    """A group of one (the cuboid) and one of the other 13 built-in objects: a single-object scene holds the
    cuboid half the time (not 1 in 14), a six-object scene almost always, never twice; without groups the
    draws are those of before."""
    from kgn_bench.data.generate import _draw_names
    from kgn_bench.shapes import OBJECTS

    objects = ("cuboid", *[n for n in OBJECTS if n != "cuboid"])
    single = GenerateConfig(mode="single", objects=objects, groups=(1, len(objects) - 1))
    rng = np.random.default_rng(0)
    assert 0.43 < np.mean([_draw_names(single, rng) == ["cuboid"] for _ in range(600)]) < 0.57
    multi = GenerateConfig(mode="multi", objects=objects, groups=(1, len(objects) - 1))
    scenes = [_draw_names(multi, rng) for _ in range(200)]
    assert all(len(set(names)) == len(names) == 6 for names in scenes)
    assert np.mean(["cuboid" in names for names in scenes]) > 0.9
    flat = GenerateConfig(mode="multi", objects=objects)
    expected = [objects[k] for k in np.random.default_rng(0).choice(len(objects), 6, replace=False)]
    assert _draw_names(flat, np.random.default_rng(0)) == expected
    assert multi.manifest()["object_groups"] == [1, len(objects) - 1] and "object_groups" not in flat.manifest()
    with pytest.raises(ValueError, match="add up to"):
        GenerateConfig(objects=objects, groups=(6, 1))
