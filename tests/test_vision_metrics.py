"""Vision metrics (GSR / GCR / OSR): matching rules, strictness, symmetry, sequential crediting, per-shape
attribution, pooling of counts, and an end-to-end run on a tiny generated dataset."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from kgn_bench.data.format import DatasetError, SceneAnnotation, scene_dir
from kgn_bench.data.generate import relabel_grasps
from kgn_bench.detectors.base import Candidates, Observation
from kgn_bench.eval.vision import (
    MESH,
    SHAPES,
    THRESHOLDS,
    ImageCounts,
    Threshold,
    VisionMetrics,
    evaluate_dataset,
    evaluate_image,
    grasp_matches,
)
from kgn_bench.geometry import invert_pose, make_pose, matrix_from_rotvec, rot_y, rot_z
from kgn_bench.grasp import GraspSet, flip_180
from kgn_bench.shapes import EVAL_DENSITY


def _poses(*translations, R=None) -> np.ndarray:
    return np.stack([make_pose(R, np.asarray(t, dtype=float)) for t in translations])


def _gs(poses: np.ndarray, collides=None) -> GraspSet:
    collides = np.zeros(len(poses), dtype=bool) if collides is None else np.asarray(collides, dtype=bool)
    return GraspSet(poses, np.full(len(poses), 0.05), collides)


def _summary(pred, gt, types, thresholds=THRESHOLDS) -> dict:
    return VisionMetrics(evaluate_image(pred, gt, types, thresholds)).summarise()


def test_thresholds_are_the_papers_in_radians():
    assert [(t.translation, t.rotation) for t in THRESHOLDS] == [
        (0.01, math.radians(20)), (0.02, math.radians(30)), (0.03, math.radians(45))]
    assert [t.label for t in THRESHOLDS] == ["1 cm / 20°", "2 cm / 30°", "3 cm / 45°"]
    assert SHAPES == ("cuboid", "cylinder", "ring", "stick", "sphere", "semi_sphere", "mesh")
    with pytest.raises(ValueError, match="positive"):
        Threshold(0.0, 0.1)


def test_perfect_predictions_score_100_percent():
    rng = np.random.default_rng(0)
    gt = []
    for centre in ((0.0, 0.0, 0.05), (0.3, 0.0, 0.05), (0.0, 0.3, 0.05)):
        poses = np.stack([make_pose(matrix_from_rotvec(rng.normal(size=3)), centre + rng.normal(0, 0.02, 3))
                          for _ in range(8)])
        gt.append(_gs(poses, collides=[False] * 6 + [True] * 2))
    pred = np.concatenate([g.free().poses for g in gt])
    s = _summary(pred, gt, ["cuboid", "ring", "stick"])
    for row in s["thresholds"]:
        assert (row["gsr"], row["gcr"], row["osr"]) == (1.0, 1.0, 1.0)
        assert (row["credited"], row["predictions"], row["gt_grasps"], row["objects"]) == (18, 18, 18, 3)
        for shape in ("cuboid", "ring", "stick"):
            assert row["per_shape"][shape]["gsr"] == 1.0 and row["per_shape"][shape]["predictions"] == 6
        assert row["per_shape"]["sphere"]["gsr"] is None and row["per_shape"]["sphere"]["objects"] == 0


def test_a_grasp_turned_180_about_its_approach_matches_a_reversed_one_does_not():
    R = matrix_from_rotvec(np.array([0.3, -0.7, 1.1]))
    g = _poses((0.1, 0.2, 0.03), R=R)
    assert grasp_matches(flip_180(g), g, THRESHOLDS[0]).all()
    reversed_approach = g.copy()
    reversed_approach[0, :3, :3] = R @ rot_y(np.pi)  # approach −x: another grasp
    assert not any(grasp_matches(reversed_approach, g, th).any() for th in THRESHOLDS)
    s = _summary(np.concatenate([flip_180(g), reversed_approach]), [_gs(g)], ["sphere"])
    assert [r["credited"] for r in s["thresholds"]] == [1, 1, 1]
    assert [r["gsr"] for r in s["thresholds"]] == [0.5, 0.5, 0.5]


def test_translation_threshold_is_strict():
    g = _poses((0.0, 0.0, 0.0))
    at = _poses((0.02, 0.0, 0.0))  # exactly 0.02 m in floating point
    below = _poses((np.nextafter(0.02, 0.0), 0.0, 0.0))
    assert np.linalg.norm(at[0, :3, 3]) == THRESHOLDS[1].translation
    assert [bool(grasp_matches(at, g, th)[0, 0]) for th in THRESHOLDS] == [False, False, True]
    assert [bool(grasp_matches(below, g, th)[0, 0]) for th in THRESHOLDS] == [False, True, True]


def test_rotation_threshold_is_strict():
    g = _poses((0.0, 0.0, 0.0))
    quarter = make_pose(np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))[None]  # d_R = π/2 exactly
    assert not grasp_matches(quarter, g, Threshold(1.0, np.pi / 2))[0, 0]
    assert grasp_matches(quarter, g, Threshold(1.0, np.nextafter(np.pi / 2, 4.0)))[0, 0]
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    th = THRESHOLDS[1]
    just_over = make_pose(matrix_from_rotvec(axis * (th.rotation + 1e-7)))[None]
    just_under = make_pose(matrix_from_rotvec(axis * (th.rotation - 1e-7)))[None]
    assert not grasp_matches(just_over, g, th)[0, 0]
    assert grasp_matches(just_under, g, th)[0, 0]


def test_a_prediction_on_two_touching_objects_is_credited_once_to_the_first():
    a, b = _poses((0.0, 0.0, 0.0)), _poses((0.015, 0.0, 0.0))
    pred = _poses((0.009, 0.0, 0.0))  # 9 mm from a, 6 mm from b: matches both at every threshold
    for gt, types, first in (([_gs(a), _gs(b)], ["cuboid", "sphere"], "cuboid"),
                             ([_gs(b), _gs(a)], ["sphere", "cuboid"], "sphere")):
        s = _summary(pred, gt, types)
        for row in s["thresholds"]:
            assert (row["gsr"], row["gcr"], row["osr"]) == (1.0, 1.0, 0.5)
            assert (row["covered"], row["objects_succeeded"], row["objects"]) == (2, 1, 2)
            second = ({"cuboid", "sphere"} - {first}).pop()
            assert row["per_shape"][first]["gsr"] == 1.0 and row["per_shape"][first]["osr"] == 1.0
            assert row["per_shape"][second]["gsr"] is None and row["per_shape"][second]["osr"] == 0.0
            assert row["per_shape"][second]["gcr"] == 1.0  # coverage ignores crediting


def test_one_prediction_covers_several_ground_truth_grasps():
    gt = _gs(_poses((0.0, 0.0, 0.0), (0.005, 0.0, 0.0), (0.0, 0.008, 0.0), (0.2, 0.0, 0.0)))
    pred = _poses((0.001, 0.0, 0.0))
    s = _summary(pred, [gt], ["cylinder"])
    assert [r["covered"] for r in s["thresholds"]] == [3, 3, 3]
    assert [r["gcr"] for r in s["thresholds"]] == [0.75, 0.75, 0.75]
    assert [r["gsr"] for r in s["thresholds"]] == [1.0, 1.0, 1.0]


def test_objects_without_collision_free_grasps_are_skipped_but_receive_their_predictions():
    blocked = _gs(_poses((0.0, 0.0, 0.0), (0.0, 0.01, 0.0)), collides=[True, True])
    free = _gs(_poses((0.3, 0.0, 0.0)))
    pred = _poses((0.0, 0.0, 0.0), (0.3, 0.0, 0.0))  # exactly on the colliding grasp, exactly on the free one
    s = _summary(pred, [blocked, free], ["stick", "ring"])
    for row in s["thresholds"]:
        assert (row["gsr"], row["gcr"], row["osr"]) == (0.5, 1.0, 1.0)
        assert (row["gt_grasps"], row["objects"]) == (1, 1)
        stick = row["per_shape"]["stick"]
        assert (stick["credited"], stick["predictions"], stick["gsr"], stick["objects"], stick["osr"]) == (
            0, 1, 0.0, 0, None)


def _brute_force(pred, gt, types, th):
    """Per-pair loops straight from the metric definitions (``kgn_bench.eval.vision``), for comparison."""
    def d_r(A, B):
        return math.acos(min(1.0, max(-1.0, (np.trace(A.T @ B) - 1.0) / 2.0)))

    def match(p, g):
        flip = g[:3, :3] @ np.diag([1.0, -1.0, -1.0])
        return (np.linalg.norm(p[:3, 3] - g[:3, 3]) < th.translation
                and min(d_r(p[:3, :3], g[:3, :3]), d_r(p[:3, :3], flip)) < th.rotation)

    taken = np.zeros(len(pred), dtype=bool)
    succ = cov = won = objects = 0
    for gs in gt:
        free = gs.free().poses
        if not len(free):
            continue
        objects += 1
        m = np.array([[match(p, g) for g in free] for p in pred]).reshape(len(pred), len(free))
        new = m.any(axis=1) & ~taken
        taken |= m.any(axis=1)
        succ += int(new.sum())
        cov += int(m.any(axis=0).sum())
        won += int(new.any())
    return succ, cov, won, objects


def test_random_scene_agrees_with_brute_force_and_per_shape_denominators_sum_to_totals():
    rng = np.random.default_rng(3)
    centres = rng.uniform(-0.05, 0.05, (5, 3))
    gt, types = [], []
    for k, c in enumerate(centres):
        n = 12
        poses = np.stack([make_pose(matrix_from_rotvec(rng.normal(size=3)), c + rng.normal(0, 0.02, 3))
                          for _ in range(n)])
        gt.append(_gs(poses, rng.random(n) < 0.3 if k != 2 else np.ones(n, bool)))
        types.append(SHAPES[k % len(SHAPES)])
    types[4] = types[0]  # two objects of one shape
    all_gt = GraspSet.concatenate(gt).poses
    pick = all_gt[rng.integers(len(all_gt), size=40)]
    pred = np.stack([make_pose(p[:3, :3] @ matrix_from_rotvec(rng.normal(0, 0.3, 3)), p[:3, 3] + rng.normal(0, 0.01, 3))
                     for p in pick])
    counts = evaluate_image(pred, gt, types)
    for k, th in enumerate(THRESHOLDS):
        succ, cov, won, objects = _brute_force(pred, gt, types, th)
        assert (counts.credited[k].sum(), counts.covered[k].sum()) == (succ, cov)
        assert (counts.objects_succeeded[k].sum(), counts.objects_evaluated[k].sum()) == (won, objects)
        assert counts.attributed[k].sum() + counts.unattributed == counts.predictions == 40
        assert np.all(counts.credited[k] <= counts.attributed[k])
    assert 0 < counts.credited[0].sum() < counts.credited[2].sum() < 40  # the test is not trivial


def test_zero_predictions_and_images_without_objects():
    gt = [_gs(_poses((0.0, 0.0, 0.0)))]
    s = _summary(np.zeros((0, 4, 4)), gt, ["cuboid"])
    assert [(r["gsr"], r["gcr"], r["osr"]) for r in s["thresholds"]] == [(None, 0.0, 0.0)] * 3
    json.dumps(s)
    metrics = VisionMetrics(evaluate_image(np.zeros((0, 4, 4)), gt, ["cuboid"]))
    assert "| 1 cm / 20° | n/a | 0.0 | 0.0 |" in metrics.to_markdown()
    lonely = evaluate_image(_poses((0.0, 0.0, 0.0)), [], [])
    assert (lonely.predictions, lonely.unattributed, int(lonely.attributed.sum())) == (1, 1, 0)
    assert VisionMetrics(lonely).summarise()["thresholds"][0]["gsr"] == 0.0


def test_counts_pool_exactly_across_images_and_processes():
    gt = [_gs(_poses((0.0, 0.0, 0.0), (0.2, 0.0, 0.0))), _gs(_poses((0.0, 0.3, 0.0)))]
    types = ["sphere", "semi_sphere"]
    one = evaluate_image(_poses((0.0, 0.0, 0.0), (0.5, 0.5, 0.5)), gt, types)  # 1 of 2 succeed
    two = evaluate_image(_poses((0.0, 0.3, 0.0), (0.2, 0.0, 0.0), (0.0, 0.0, 0.0), (0.9, 0.0, 0.0)), gt, types)
    pooled = one + two
    restored = ImageCounts.from_dict(json.loads(json.dumps(one.to_dict()))) + two
    assert restored.to_dict() == pooled.to_dict() == (two + one).to_dict()
    metrics = VisionMetrics.empty()
    metrics.add(one)
    metrics.add(two)
    row = metrics.summarise()["thresholds"][1]
    assert (row["gsr"], row["gcr"], row["osr"]) == (4 / 6, 4 / 6, 3 / 4)  # pooled: not the mean of 1/2 and 3/4
    # (0.5, 0.5, 0.5) is nearest to the semi-sphere's grasp, (0.9, 0, 0) to the sphere's (0.2, 0, 0)
    assert (row["per_shape"]["sphere"]["predictions"], row["per_shape"]["semi_sphere"]["predictions"]) == (4, 2)
    assert (row["per_shape"]["sphere"]["gsr"], row["per_shape"]["semi_sphere"]["gsr"]) == (3 / 4, 1 / 2)
    with pytest.raises(ValueError, match="different thresholds"):
        one + evaluate_image(np.zeros((0, 4, 4)), gt, types, THRESHOLDS[:1])


def test_malformed_inputs_are_refused_with_one_line_messages():
    gt = [_gs(_poses((0.0, 0.0, 0.0)))]
    with pytest.raises(ValueError, match=r"\(N, 4, 4\)"):
        evaluate_image(np.eye(4), gt, ["cuboid"])
    with pytest.raises(ValueError, match="finite"):
        evaluate_image(np.full((1, 4, 4), np.nan), gt, ["cuboid"])
    with pytest.raises(ValueError, match="1 GT grasp sets for 2 object types"):
        evaluate_image(np.zeros((0, 4, 4)), gt, ["cuboid", "ring"])
    with pytest.raises(ValueError, match="unknown object type 'mug'"):
        evaluate_image(np.zeros((0, 4, 4)), gt, ["mug"])


def test_markdown_lists_every_threshold_and_shape():
    gt = [_gs(_poses((0.0, 0.0, 0.0)))]
    text = VisionMetrics(evaluate_image(_poses((0.0, 0.0, 0.0)), gt, ["ring"])).to_markdown()
    for th in THRESHOLDS:
        assert f"| {th.label} | 100.0 | 100.0 | 100.0 | 1 / 1 | 1 / 1 | 1 / 1 |" in text
    assert "| ring | 100.0 / 100.0 / 100.0 | 100.0 / 100.0 / 100.0 | 100.0 / 100.0 / 100.0 | 1 | 1 |" in text
    assert all(f"| {s} |" in text for s in SHAPES if s != MESH) and f"| {MESH} |" not in text  # no mesh object


def test_ground_truth_detector_scores_100_percent_on_a_generated_dataset(tiny_dataset):
    root, config = tiny_dataset
    truth, objects = {}, {}
    for i in range(config.scenes):
        ann = SceneAnnotation.load(scene_dir(root, i) / "scene.json")
        labelled = relabel_grasps(ann, EVAL_DENSITY)
        free = GraspSet.concatenate([g.free() for g in labelled])
        objects[i] = sum(int(len(g.free()) > 0) for g in labelled)
        for pose in ann.camera_poses:
            truth[pose.tobytes()] = free

    def oracle(obs: Observation) -> Candidates:
        g = truth[obs.camera_pose.tobytes()].transformed(invert_pose(obs.camera_pose))  # camera frame
        n = len(g)
        return Candidates(g.poses, g.widths, np.ones(n), np.full(n, np.nan))

    metrics = evaluate_dataset(oracle, root, split="test", progress=False)
    s = metrics.summarise()
    test_scene = int((root / "test.txt").read_text().split()[0])
    n_free = len(truth[SceneAnnotation.load(scene_dir(root, test_scene) / "scene.json").camera_poses[0].tobytes()])
    assert s["images"] == config.views and s["predictions"] == config.views * n_free
    for row in s["thresholds"]:
        assert (row["gsr"], row["gcr"], row["osr"]) == (1.0, 1.0, 1.0)
        assert row["gt_grasps"] == config.views * n_free and row["objects"] == config.views * objects[test_scene]
    json.dumps(s)

    class Nothing:
        name, privileged = "nothing", False

        def __init__(self):
            self.seeds = []

        def reset(self, seed):
            self.seeds.append(seed)

        def detect(self, obs):
            return Candidates.empty()

    detector = Nothing()
    train = evaluate_dataset(detector, root, split="train", views=3, progress=False).summarise()
    assert train["images"] == 3 and train["predictions"] == 0
    assert [r["gsr"] for r in train["thresholds"]] == [None] * 3
    train_scenes = [int(x) for x in (root / "train.txt").read_text().split()]
    assert detector.seeds == [[train_scenes[0], 0], [train_scenes[0], 1], [train_scenes[1], 0]]
    (root / "empty.txt").write_text("")
    with pytest.raises(DatasetError, match="has no scenes"):
        evaluate_dataset(oracle, root, split="empty", progress=False)
    (root / "empty.txt").unlink()


def test_paper_rotation_threshold_in_degrees():
    """A grasp turned 19.9° about its closing axis matches at (1 cm, 20°); one turned 20.1° does not."""
    g = _poses((0.0, 0.0, 0.0))
    turned = make_pose(rot_z(math.radians(19.9)))[None]
    assert grasp_matches(turned, g, THRESHOLDS[0])[0, 0]
    assert not grasp_matches(make_pose(rot_z(math.radians(20.1)))[None], g, THRESHOLDS[0])[0, 0]


def test_an_imported_object_counts_in_the_mesh_column(object_library):
    """An imported object's predictions and grasps go to the ``mesh`` column, which the table then shows."""
    gt = [_gs(_poses((0.0, 0.0, 0.0)))]
    counts = evaluate_image(_poses((0.0, 0.0, 0.0)), gt, ["test_block"])
    j = SHAPES.index(MESH)
    assert counts.credited[0, j] == 1 and counts.credited[0, :j].sum() == 0
    assert f"| {MESH} | 100.0 / 100.0 / 100.0 |" in VisionMetrics(counts).to_markdown()
    old = counts.to_dict()
    old["shapes"] = list(SHAPES[:-1])  # counts stored before the mesh column read with an empty one
    for name in ("attributed", "credited", "covered", "gt", "objects_succeeded", "objects_evaluated"):
        old[name] = [row[:-1] for row in old[name]]
    assert ImageCounts.from_dict(old).credited[0, j] == 0
