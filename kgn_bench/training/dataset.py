"""Training samples from a PS dataset: augmented network inputs and KGN / KGNv2 targets.

One sample is one view of one scene of a split. Its ground truth is every collision-free grasp of every
object of the scene (world frame in ``scene.json``), moved into the view's OpenCV camera frame with
``T_cam_grasp = T_world_cam⁻¹ · T_world_grasp``, then encoded by ``model.targets.encode_targets`` through the
image → output affine of the augmentation.

Augmentation (``AugmentConfig``; training only, seeded per (seed, epoch, item)):

* crop and zoom: a crop of the full frame, ``input_size / σ · m`` image px with ``m ~ U[zoom]``
  (``m > 1`` shows more of the scene, objects smaller than at inference), centred at a uniformly drawn
  point of the central ``center_fraction`` of the image, warped to ``input_size`` (``preprocess.affine_for_crop``);
* horizontal flip with probability ``flip``: the input is mirrored; the keypoint targets are
  re-canonicalised by the target code (L↔R, TL↔TR), which works in output coordinates; the scale and
  width targets are unchanged;
* colour: brightness, contrast and saturation factors ``1 + U(±colour)`` in random order;
* depth noise: ``N(0, depth_noise²)`` clipped to ±``depth_clip`` on valid pixels only (holes stay holes,
  unlike the reference implementation, which also noises the 0 pixels).

Evaluation samples (``augment=None``) use the inference path: the full frame resized by σ.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from kgn_bench.data.format import DatasetError, SceneAnnotation, read_split, read_view, scene_dir
from kgn_bench.grasp import GraspSet
from kgn_bench.model.preprocess import InputConfig, affine_for_crop, output_affine, prepare, standardize, warp_images
from kgn_bench.model.targets import ASSIGNMENTS, OUTPUT_STRIDE, OUTPUT_STRIDES, encode_targets
from kgn_bench.model.variants import Variant

__all__ = ["AugmentConfig", "GraspViewDataset", "camera_frame_grasps"]


@dataclass(frozen=True)
class AugmentConfig:
    """Training augmentation; see the module docstring. ``input_size`` = (width, height) in px."""

    input_size: tuple[int, int] = (256, 256)
    zoom: tuple[float, float] = (0.75, 1.3)
    center_fraction: float = 0.5
    flip: float = 0.5
    colour: float = 0.4
    depth_noise: float = 0.001
    depth_clip: float = 0.005

    def __post_init__(self) -> None:
        w, h = self.input_size
        if w % 32 or h % 32 or w <= 0 or h <= 0:
            raise ValueError(f"augment input_size must be positive multiples of 32, got {self.input_size}")
        if not 0.0 < self.zoom[0] <= self.zoom[1]:
            raise ValueError(f"augment zoom must be an increasing positive range, got {self.zoom}")
        if not 0.0 <= self.center_fraction <= 1.0 or not 0.0 <= self.flip <= 1.0:
            raise ValueError("augment center_fraction and flip must lie in [0, 1]")
        if self.colour < 0 or self.depth_noise < 0 or self.depth_clip < 0:
            raise ValueError("augment colour, depth_noise and depth_clip must be ≥ 0")


def camera_frame_grasps(annotation: SceneAnnotation, view: int) -> GraspSet:
    """All collision-free grasps of the scene in view ``view``'s camera frame (``T_cam_grasp``)."""
    world = GraspSet.concatenate([o.grasps.free() for o in annotation.objects])
    return world.transformed(np.linalg.inv(annotation.camera_poses[view]))


def _colour_jitter(rgb: np.ndarray, strength: float, rng: np.random.Generator) -> np.ndarray:
    """Brightness, contrast, saturation (random order) on float RGB in [0, 255]."""
    out = rgb
    for op in rng.permutation(3):
        a = 1.0 + rng.uniform(-strength, strength)
        if op == 0:
            out = out * a
        else:
            grey = out @ np.array([0.299, 0.587, 0.114], dtype=np.float32)
            ref = np.float32(grey.mean()) if op == 1 else grey[..., None]
            out = ref + a * (out - ref)
    return np.clip(out, 0.0, 255.0).astype(np.float32)


class GraspViewDataset(Dataset):
    """Views of the scenes of ``split`` of the dataset at ``root`` as (input, targets) pairs.

    ``__getitem__`` returns ``(x (4, H_in, W_in) float32 tensor, targets dict of tensors)`` in the format
    of ``model.targets.encode_targets`` (with the view's stored depth as the scale anchor's depth and the
    ``assignment`` rule of ``model.targets``), for a network of output stride ``stride`` (4 or 2; the targets
    are maps of the input size divided by it). ``set_epoch`` changes the augmentation draws.
    """

    def __init__(self, root: Path, split: str, variant: Variant, input_config: InputConfig | None = None,
                 augment: AugmentConfig | None = None, seed: int = 0, limit: int | None = None,
                 cache_scenes: int = 64, assignment: str = "first", stride: int = OUTPUT_STRIDE,
                 heatmap_radius: int = 1) -> None:
        if assignment not in ASSIGNMENTS:
            raise ValueError(f"unknown assignment {assignment!r} (known: {', '.join(ASSIGNMENTS)})")
        if stride not in OUTPUT_STRIDES:
            raise ValueError(f"output stride must be one of {OUTPUT_STRIDES}, got {stride}")
        if heatmap_radius < 1:
            raise ValueError(f"heatmap radius must be at least 1, got {heatmap_radius}")
        self.assignment, self.stride, self.heatmap_radius = assignment, stride, heatmap_radius
        self.root = Path(root)
        self.variant, self.augment, self.seed = variant, augment, seed
        self.input_config = input_config or InputConfig()
        scenes = read_split(self.root, split)
        first = SceneAnnotation.load(scene_dir(self.root, scenes[0]) / "scene.json") if scenes else None
        if first is None:
            raise DatasetError(f"{self.root}: split {split!r} is empty")
        views = len(first.camera_poses)
        self.items = [(s, v) for s in scenes for v in range(views)][:limit]
        self.epoch = 0
        self._cache: OrderedDict[int, SceneAnnotation] = OrderedDict()
        self._cache_size = cache_scenes

    def __len__(self) -> int:
        return len(self.items)

    def set_epoch(self, epoch: int) -> None:
        self.epoch = epoch

    def annotation(self, scene: int) -> SceneAnnotation:
        if scene in self._cache:
            self._cache.move_to_end(scene)
            return self._cache[scene]
        ann = SceneAnnotation.load(scene_dir(self.root, scene) / "scene.json")
        self._cache[scene] = ann
        if len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        return ann

    def sample(self, index: int) -> tuple[np.ndarray, np.ndarray, tuple[int, int], SceneAnnotation, int]:
        """``(x (4, H, W) float32, M image → output, out_shape, annotation, view)`` of item ``index``."""
        return self._sample(index)[:5]

    def _sample(self, index: int) -> tuple[np.ndarray, np.ndarray, tuple[int, int], SceneAnnotation, int, np.ndarray]:
        """``sample`` and the view's stored depth image (H, W) metres, before any augmentation."""
        scene, view = self.items[index]
        ann = self.annotation(scene)
        rgbd = read_view(scene_dir(self.root, scene), view)
        if self.augment is None:
            x, M, _ = prepare(rgbd.rgb, rgbd.depth, self.input_config, self.stride)
            # targets cover the padded maps, the same shape as the network's output
            return x.numpy(), M, (x.shape[1] // self.stride, x.shape[2] // self.stride), ann, view, rgbd.depth
        aug = self.augment
        rng = np.random.default_rng([self.seed, self.epoch, index])
        h, w = rgbd.depth.shape
        w_in, h_in = aug.input_size
        m = rng.uniform(*aug.zoom)
        crop = (w_in / self.input_config.input_scale * m, h_in / self.input_config.input_scale * m)
        f = aug.center_fraction
        centre = (rng.uniform((1 - f) / 2, (1 + f) / 2) * (w - 1), rng.uniform((1 - f) / 2, (1 + f) / 2) * (h - 1))
        A = affine_for_crop(centre, crop, aug.input_size, flip=bool(rng.random() < aug.flip))
        rgb, depth = warp_images(rgbd.rgb, rgbd.depth, A, aug.input_size, self.input_config)
        if aug.colour > 0:
            rgb = _colour_jitter(rgb, aug.colour, rng)
        if aug.depth_noise > 0:
            noise = np.clip(rng.normal(0.0, aug.depth_noise, depth.shape), -aug.depth_clip, aug.depth_clip)
            depth = np.where(depth > 0, depth + noise.astype(np.float32), 0.0).astype(np.float32)
        x = standardize(rgb, depth, self.input_config)
        return x, output_affine(A, self.stride), (h_in // self.stride, w_in // self.stride), ann, view, rgbd.depth

    def __getitem__(self, index: int) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
        x, M, out_shape, ann, view, depth = self._sample(index)
        grasps = camera_frame_grasps(ann, view)
        targets = encode_targets(grasps.poses, grasps.widths, ann.intrinsics.K, M, out_shape, self.variant, depth,
                                 self.assignment, self.heatmap_radius)
        return torch.from_numpy(np.ascontiguousarray(x)), {k: torch.from_numpy(v) for k, v in targets.items()}

