"""Training samples from a real generated dataset: shapes, augmentation geometry, flip canonicalisation."""

from dataclasses import replace

import numpy as np
import pytest
import torch

from kgn_bench.model.preprocess import prepare
from kgn_bench.model.targets import apply_affine, project_keypoints
from kgn_bench.model.variants import get_variant
from kgn_bench.training.dataset import AugmentConfig, GraspViewDataset, camera_frame_grasps

V2 = get_variant("kgnv2")


def test_evaluation_sample_is_the_inference_input(tiny_dataset):
    root, _ = tiny_dataset
    ds = GraspViewDataset(root, "test", V2)
    x, M, out_shape, _, view = ds.sample(0)
    from kgn_bench.data.format import read_view, scene_dir

    rgbd = read_view(scene_dir(root, ds.items[0][0]), view)
    x_ref, M_ref, _ = prepare(rgbd.rgb, rgbd.depth)
    np.testing.assert_array_equal(x, x_ref.numpy())
    np.testing.assert_array_equal(M, M_ref)
    assert out_shape == (x.shape[1] // 4, x.shape[2] // 4)
    _, targets = ds[0]
    assert targets["hm"].shape == (9, *out_shape)
    assert int(targets["mask"].sum()) > 0


def test_stride_two_targets_are_the_finer_maps(tiny_dataset):
    root, _ = tiny_dataset
    four, two = GraspViewDataset(root, "test", V2), GraspViewDataset(root, "test", V2, stride=2)
    x4, M4, shape4, _, _ = four.sample(0)
    x2, M2, shape2, _, _ = two.sample(0)
    np.testing.assert_array_equal(x2, x4)
    np.testing.assert_allclose(M2, 2.0 * M4)
    assert shape2 == (x2.shape[1] // 2, x2.shape[2] // 2) == (2 * shape4[0], 2 * shape4[1])
    t4, t2 = four[0][1], two[0][1]
    assert t2["hm"].shape == (9, *shape2)
    # the keypoint offsets are in output cells: twice as many at stride 2 for the grasps both keep
    n = int(t4["mask"].sum())
    assert int(t2["mask"].sum()) >= n > 0
    k4 = np.abs(t4["kpts"].numpy()[:n]).max()
    k2 = np.abs(t2["kpts"].numpy()[: int(t2["mask"].sum())]).max()
    assert 1.8 * k4 < k2 < 2.2 * k4
    with pytest.raises(ValueError, match="output stride"):
        GraspViewDataset(root, "test", V2, stride=8)
    wide = GraspViewDataset(root, "test", V2, stride=2, heatmap_radius=2)[0][1]
    peaks = t2["hm"] == 1.0
    assert torch.equal(wide["hm"] == 1.0, peaks) and torch.equal(wide["mask"], t2["mask"])
    assert int((wide["hm"] > 0).sum()) > 2 * int((t2["hm"] > 0).sum())


@pytest.mark.parametrize("flip", [0.0, 1.0])
def test_augmented_targets_sit_where_the_grasps_land(tiny_dataset, flip):
    root, _ = tiny_dataset
    aug = AugmentConfig(input_size=(128, 96), flip=flip, colour=0.0, depth_noise=0.0)
    ds = GraspViewDataset(root, "train", V2, augment=aug, seed=3)
    x, M, out_shape, ann, view = ds.sample(1)
    assert x.shape == (4, 96, 128) and out_shape == (24, 32)
    _, targets = ds[1]
    n = int(targets["mask"].sum())
    assert n > 0
    hm = targets["hm"].numpy()
    ind = targets["ind"].numpy()[:n]
    bins = targets["bin"].numpy()[:n]
    ys, xs = np.divmod(ind, out_shape[1])
    assert np.all(hm[bins, ys, xs] == 1.0)  # every kept grasp peaks at its cell
    # the centres of the camera-frame ground truth, mapped by M, include every target cell + reg
    grasps = camera_frame_grasps(ann, view)
    sides = V2.box_sides(np.linalg.norm(grasps.poses[:, :3, 3], axis=1))
    _, centres = project_keypoints(grasps.poses, ann.intrinsics.K, sides)
    out_centres = apply_affine(M, centres)
    cells = np.stack([xs, ys], axis=1) + targets["reg"].numpy()[:n]
    d = np.linalg.norm(cells[:, None] - out_centres[None], axis=-1).min(axis=1)
    assert d.max() < 1e-4
    # canonical order in output coordinates: L left of (or level with) R, flipped or not
    k = targets["kpts"].numpy()[:n].reshape(n, 4, 2)
    assert np.all(k[:, 0, 0] <= k[:, 1, 0] + 1e-5)
    assert (M[0, 0] < 0) == (flip == 1.0)


def test_augmentation_is_seeded_and_keeps_depth_holes(tiny_dataset):
    root, _ = tiny_dataset
    aug = AugmentConfig(input_size=(128, 128))
    a = GraspViewDataset(root, "train", V2, augment=aug, seed=1)
    b = GraspViewDataset(root, "train", V2, augment=aug, seed=1)
    np.testing.assert_array_equal(a.sample(0)[0], b.sample(0)[0])
    b.set_epoch(1)
    assert not np.array_equal(a.sample(0)[0], b.sample(0)[0])
    # depth noise: within ±depth_clip on valid pixels, none on holes and crop borders (zoomed out: borders)
    wide = AugmentConfig(input_size=(128, 128), zoom=(2.5, 2.5), colour=0.0)
    noisy = GraspViewDataset(root, "train", V2, augment=wide, seed=1).sample(0)[0][3]
    clean = GraspViewDataset(root, "train", V2, augment=replace(wide, depth_noise=0.0), seed=1).sample(0)[0][3]
    holes = clean == 0.0
    assert holes.any() and np.all(noisy[holes] == 0.0)
    diff = (noisy - clean)[~holes] * 0.2  # standardised → metres (depth std 0.2 m)
    assert 0.0 < np.abs(diff).max() <= wide.depth_clip + 1e-6


def test_augment_config_rejects_bad_values():
    with pytest.raises(ValueError, match="multiples of 32"):
        AugmentConfig(input_size=(100, 128))
    with pytest.raises(ValueError, match="zoom"):
        AugmentConfig(zoom=(1.2, 0.8))
