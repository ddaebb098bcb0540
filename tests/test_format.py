import json

import numpy as np
import pytest

from kgn_bench.data.format import (
    DatasetError,
    SceneAnnotation,
    decode_depth,
    encode_depth,
    read_split,
    read_view,
    scene_dir,
)


def test_depth_codec_is_lossless_to_a_tenth_of_a_millimetre(rng):
    depth = rng.uniform(0.3, 2.0, size=(40, 50)).astype(np.float32)
    depth[0, :5] = [0.0, np.nan, np.inf, 7.0, -1.0]
    back = decode_depth(encode_depth(depth))
    ok = np.isfinite(depth) & (depth > 0) & (depth < 6.5)
    assert np.abs(back[ok] - depth[ok]).max() <= 0.5e-4 + 1e-7
    np.testing.assert_array_equal(back[0, :5], 0.0)


def test_annotation_round_trips_and_views_load(tiny_dataset):
    root, config = tiny_dataset
    folder = scene_dir(root, 1)
    ann = SceneAnnotation.load(folder / "scene.json")
    again = SceneAnnotation.from_json(json.loads(json.dumps(ann.to_json())))
    assert again.to_json() == ann.to_json()
    assert [o.type for o in ann.objects] and len(ann.objects) == 6
    assert ann.camera_poses.shape == (config.views, 4, 4)
    view = read_view(folder, 1)
    assert view.rgb.shape == (480, 640, 3) and view.depth.dtype == np.float32
    assert set(np.unique(view.mask)) <= set(range(7))


def test_malformed_annotations_give_named_errors(tiny_dataset, tmp_path):
    root, _ = tiny_dataset
    data = json.loads((scene_dir(root, 0) / "scene.json").read_text())
    data["objects"][2]["type"] = "teapot"
    with pytest.raises(DatasetError, match=r"objects\[2\].*teapot"):
        SceneAnnotation.from_json(data)
    bad = tmp_path / "scene.json"
    bad.write_text("{not json")
    with pytest.raises(DatasetError, match="not valid JSON"):
        SceneAnnotation.load(bad)
    with pytest.raises(DatasetError, match="missing or unreadable"):
        read_view(tmp_path, 0)
    with pytest.raises(DatasetError, match="no split file"):
        read_split(tmp_path, "train")
