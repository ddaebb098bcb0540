"""The PS dataset on disk: layout, annotation schema and image codecs.

Layout of a dataset folder::

    DIR/dataset.json                 manifest: format version and the settings that generated it
    DIR/train.txt, DIR/test.txt      scene-wise split, one scene index per line (written last)
    DIR/scenes/00012/scene.json      annotation of scene 12 (below)
    DIR/scenes/00012/rgb_3.png       view 3: RGB, 8-bit PNG
    DIR/scenes/00012/depth_3.png     planar depth, 16-bit PNG in units of 0.1 mm (0 = no return)
    DIR/scenes/00012/mask_3.png      instance labels, 8-bit PNG (0 = table/background, i+1 = object i)

``scene.json`` holds ``intrinsics`` (fx, fy, cx, cy, width, height), ``camera_poses`` (V × 4 × 4,
OpenCV camera-to-world), and ``objects``: per object its ``type``, ``dims`` (metres), ``pose``
(4 × 4 ``T_world_obj``), ``color`` (RGB in [0, 1]), ``mass`` (kg) and ``grasps``: ``poses`` (N × 4 × 4,
world frame, grasp frame of ``kgn_bench.grasp``), ``widths`` (N, metres) and ``collides`` (N, bool).
A scene folder is written under a temporary name and renamed when complete, so a folder named by its
index is always whole.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from kgn_bench.camera import Intrinsics
from kgn_bench.errors import KGNBenchError
from kgn_bench.grasp import GraspSet
from kgn_bench.shapes import GraspDensity, shape_from_dims
from kgn_bench.types import RGBD

__all__ = [
    "DEPTH_UNIT",
    "FORMAT_VERSION",
    "DatasetError",
    "ObjectAnnotation",
    "SceneAnnotation",
    "read_manifest",
    "read_split",
    "read_view",
    "scene_dir",
    "view_paths",
    "write_view",
]

FORMAT_VERSION = 1
DEPTH_UNIT = 1e-4
"""Metres per count of the 16-bit depth PNG (0.1 mm; the range ends at 6.5535 m)."""


class DatasetError(KGNBenchError, ValueError):
    """A dataset file is missing, malformed or inconsistent."""


@dataclass
class ObjectAnnotation:
    type: str
    dims: dict
    pose: np.ndarray
    color: tuple[float, float, float]
    mass: float
    grasps: GraspSet = field(default_factory=GraspSet.empty)

    def to_json(self) -> dict:
        return {
            "type": self.type,
            "dims": self.dims,
            "pose": self.pose.tolist(),
            "color": list(self.color),
            "mass": self.mass,
            "grasps": {
                "poses": self.grasps.poses.tolist(),
                "widths": self.grasps.widths.tolist(),
                "collides": self.grasps.collides.astype(bool).tolist(),
            },
        }

    @classmethod
    def from_json(cls, d: dict, where: str) -> ObjectAnnotation:
        try:
            shape_from_dims(d["type"], d["dims"])  # validates type and sizes
            pose = np.asarray(d["pose"], dtype=float)
            g = d["grasps"]
            grasps = GraspSet(
                np.asarray(g["poses"], dtype=float).reshape(-1, 4, 4),
                np.asarray(g["widths"], dtype=float),
                np.asarray(g["collides"], dtype=bool),
            )
            obj = cls(d["type"], d["dims"], pose, tuple(d["color"]), float(d["mass"]), grasps)
        except (KeyError, TypeError, ValueError) as e:
            raise DatasetError(f"{where}: {type(e).__name__}: {e}") from None
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise DatasetError(f"{where}: pose must be a finite 4x4 matrix")
        return obj


@dataclass
class SceneAnnotation:
    """Everything known about one generated scene (see the module docstring for the JSON schema)."""

    index: int
    intrinsics: Intrinsics
    camera_poses: np.ndarray
    objects: list[ObjectAnnotation]
    density: GraspDensity

    def to_json(self) -> dict:
        return {
            "format_version": FORMAT_VERSION,
            "scene": self.index,
            "intrinsics": self.intrinsics.to_dict(),
            "camera_poses": self.camera_poses.tolist(),
            "grasp_density": {"translations": self.density.translations, "angles": self.density.angles},
            "objects": [o.to_json() for o in self.objects],
        }

    @classmethod
    def from_json(cls, d: dict, where: str = "scene.json") -> SceneAnnotation:
        try:
            if d.get("format_version") != FORMAT_VERSION:
                raise DatasetError(f"{where}: format_version {d.get('format_version')!r}, expected {FORMAT_VERSION}")
            cams = np.asarray(d["camera_poses"], dtype=float)
            if cams.ndim != 3 or cams.shape[1:] != (4, 4):
                raise DatasetError(f"{where}: camera_poses must be V x 4 x 4, got shape {cams.shape}")
            objects = [ObjectAnnotation.from_json(o, f"{where}: objects[{i}]") for i, o in enumerate(d["objects"])]
            dens = d["grasp_density"]
            return cls(
                int(d["scene"]),
                Intrinsics.from_dict(d["intrinsics"]),
                cams,
                objects,
                GraspDensity(int(dens["translations"]), int(dens["angles"])),
            )
        except DatasetError:
            raise
        except (KeyError, TypeError, ValueError) as e:
            raise DatasetError(f"{where}: {type(e).__name__}: {e}") from None

    @classmethod
    def load(cls, path: Path) -> SceneAnnotation:
        try:
            text = Path(path).read_text()
        except OSError as e:
            raise DatasetError(f"cannot read {path}: {e.strerror}") from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as e:
            raise DatasetError(f"{path}: not valid JSON ({e})") from None
        return cls.from_json(data, str(path))


def scene_dir(root: Path, index: int) -> Path:
    return Path(root) / "scenes" / f"{index:05d}"


def view_paths(folder: Path, view: int) -> tuple[Path, Path, Path]:
    """Paths of the RGB, depth and mask PNGs of one view inside a scene folder."""
    folder = Path(folder)
    return folder / f"rgb_{view}.png", folder / f"depth_{view}.png", folder / f"mask_{view}.png"


def _imwrite(path: Path, image: np.ndarray) -> None:
    if not cv2.imwrite(str(path), image, [cv2.IMWRITE_PNG_COMPRESSION, 1]):
        raise OSError(f"could not write {path}")


def encode_depth(depth: np.ndarray) -> np.ndarray:
    """Float metres → uint16 counts of ``DEPTH_UNIT``; beyond 6.5535 m (or non-finite) becomes 0."""
    counts = np.rint(np.nan_to_num(depth, nan=0.0, posinf=0.0, neginf=0.0) / DEPTH_UNIT)
    counts[(counts < 0) | (counts > np.iinfo(np.uint16).max)] = 0
    return counts.astype(np.uint16)


def decode_depth(counts: np.ndarray) -> np.ndarray:
    return counts.astype(np.float32) * np.float32(DEPTH_UNIT)


def write_view(folder: Path, view: int, rgbd: RGBD) -> None:
    rgb_p, depth_p, mask_p = view_paths(folder, view)
    _imwrite(rgb_p, cv2.cvtColor(rgbd.rgb, cv2.COLOR_RGB2BGR))
    _imwrite(depth_p, encode_depth(rgbd.depth))
    _imwrite(mask_p, rgbd.mask)


def read_view(folder: Path, view: int) -> RGBD:
    """Load one view; ``DatasetError`` if a file is missing or unreadable."""
    rgb_p, depth_p, mask_p = view_paths(folder, view)
    images = []
    for p, flag in ((rgb_p, cv2.IMREAD_COLOR), (depth_p, cv2.IMREAD_UNCHANGED), (mask_p, cv2.IMREAD_UNCHANGED)):
        img = cv2.imread(str(p), flag)
        if img is None:
            raise DatasetError(f"missing or unreadable image {p}")
        images.append(img)
    rgb, depth, mask = images
    if depth.dtype != np.uint16 or mask.dtype != np.uint8:
        raise DatasetError(f"unexpected image types in {folder} view {view}: depth {depth.dtype}, mask {mask.dtype}")
    return RGBD(rgb=cv2.cvtColor(rgb, cv2.COLOR_BGR2RGB), depth=decode_depth(depth), mask=mask)


def read_manifest(root: Path) -> dict:
    path = Path(root) / "dataset.json"
    if not path.is_file():
        raise DatasetError(f"{root} is not a dataset folder (no dataset.json)")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path}: not valid JSON ({e})") from None


def read_split(root: Path, name: str) -> list[int]:
    """Scene indices of split ``name`` (train or test)."""
    path = Path(root) / f"{name}.txt"
    if not path.is_file():
        raise DatasetError(f"no split file {path} (is the dataset complete?)")
    try:
        return [int(line) for line in path.read_text().split()]
    except ValueError:
        raise DatasetError(f"{path}: malformed split file") from None
