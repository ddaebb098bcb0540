"""The test views of a split: order, count, ground truth per object, and a detector called per view."""

import numpy as np
import pytest

from kgn_bench.data.format import SceneAnnotation, read_split, scene_dir
from kgn_bench.eval import views as eval_views
from kgn_bench.eval.views import detector_call, iter_views
from kgn_bench.types import Candidates


def test_views_come_in_split_order_with_their_ground_truth(tiny_dataset):
    root, config = tiny_dataset
    scenes = read_split(root, "test")
    seconds = {}
    total, items = iter_views(root, "test", views=None, seconds=seconds)
    items = list(items)
    assert total == len(items) == len(scenes) * config.views
    assert [(v.scene, v.view) for v in items] == [(s, k) for s in scenes for k in range(config.views)]
    first = items[0]
    ann = SceneAnnotation.load(scene_dir(root, scenes[0]) / "scene.json")
    assert first.types == [o.type for o in ann.objects] and len(first.gt) == len(ann.objects)
    np.testing.assert_array_equal(first.observation.camera_pose, ann.camera_poses[0])
    assert first.observation.depth.shape == first.observation.rgb.shape[:2]
    assert set(seconds) == {"read", "ground_truth"} and seconds["read"] > 0


def test_views_cap_and_refusals(tiny_dataset):
    root, _ = tiny_dataset
    total, items = iter_views(root, "test", views=1)
    assert total == 1 and len(list(items)) == 1
    with pytest.raises(ValueError, match="views must be"):
        iter_views(root, "test", views=0)


class _Seeded:
    """A ``Detector``: records its resets and returns no candidates (or ``reply``)."""

    name = "seeded"
    privileged = False

    def __init__(self, reply=None):
        self.resets, self.reply = [], reply

    def reset(self, seed):
        self.resets.append(list(seed))

    def detect(self, observation):
        return Candidates.empty() if self.reply is None else self.reply


def test_detector_call_resets_a_detector_per_view_and_checks_the_reply():
    view = eval_views.TestView(4, 1, observation=None, gt=[], types=[])
    det = _Seeded()
    assert len(detector_call(det)(view)) == 0 and det.resets == [[4, 1]]
    assert len(detector_call(lambda obs: Candidates.empty())(view)) == 0
    with pytest.raises(TypeError, match="expected Candidates"):
        detector_call(_Seeded(reply=[]))(view)
    with pytest.raises(TypeError, match="must be a Detector or a callable"):
        detector_call(3)
