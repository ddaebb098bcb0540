"""The learned detector ``vgn``: VGN (Breyer et al., CoRL 2020) as GIGA (Jiang et al., RSS 2021) re-trained it
for one noisy side view. Depth → TSDF of the workspace cube → ``VGNNet`` → VGN's voxel selection.

**Frames.** The grid frame has the world's axes and its origin at the workspace cube's corner
(``T_world_grid`` = translation by ``giga.WORKSPACE_ORIGIN``; ``kgn_bench.tsdf``). The network predicts, at
every voxel ``(i, j, k)``, a quality, a width (voxels) and the unit quaternion (w, x, y, z) of ``R_grid_grasp``
in this project's grasp frame (origin at the fingertip midpoint, +x approach, z the closing axis;
``kgn_bench.grasp``); ``q`` and ``q · R_x(π)`` are the same grasp.

**detect(obs)**:

1. fuse ``obs.depth`` (planar metres; 0 or NaN = no reading) seen from ``obs.camera_pose`` (``T_world_cam``,
   OpenCV axes) into a ``TSDFVolume`` over the checkpoint's grid (GIGA's: 30 cm, 40³, τ = 4 voxels) placed at
   ``T_world_grid``; the network input is ``TSDFVolume.network_input`` ((t + 1)/2 in the surface band, else 0);
2. one forward pass;
3. ``select_grasps`` (a pure numpy function, below): Gaussian smoothing of the quality, the surface, width
   and (GIGA) border masks, the threshold, non-maximum suppression, sorted by quality descending;
4. each kept voxel ``(i, j, k)`` is a grasp whose reference point (VGN's TCP, ``giga.GRASP_REFERENCE_DEPTH``
   behind the fingertips) sits at ``(i, j, k) · voxel``: VGN's convention puts the grasp at the voxel's *index*
   times the voxel size, not at its centre ``(idx + ½) · voxel`` where the TSDF samples (VGN and GIGA label and
   decode this way, so the network learnt that offset; keep it). In this project's grasp frame (origin at the
   fingertips) that is ``T_grid_grasp = [R(q) | (i, j, k) · voxel + GRASP_REFERENCE_DEPTH · R(q) x̂]``, then
   ``T_cam_grasp = T_world_cam⁻¹ · T_world_grid · T_grid_grasp``; width = width_voxels · voxel (m);
   confidence = the smoothed quality; no reprojection error (NaN, as every non-keypoint detector).

**Selection defaults: GIGA's** (``GIGA_SELECTION``), because GIGA's Table I (VGN re-trained single-view:
packed 74.5 % / pile 60.7 % GSR) is what this detector is calibrated against: quality floor 0.5 with
``--force`` (keep every NMS maximum ≥ 0.9; if there is none, only the single best one ≥ 0.5), the surface
mask with GIGA's outside threshold 0.1 (GIGA's ``sim_grasp_multiple.py`` passes ``out_th = 0.1``, VGN's
default is 0.5), GIGA's border mask and ranking by quality (GIGA's ``--best``). ``VGN_SELECTION`` is the
original VGN's (threshold 0.9, no forcing, outside threshold 0.5, no border mask); VGN itself then executes a
*random* one of the kept grasps, which the harness does not reproduce (candidates are always sorted).

Weights: ``assets/weights/vgn.pt`` with its model card ``vgn.md`` (``model.vgn_checkpoint``); a name looks
up ``assets/weights/<name>.pt``, a path loads that file. A missing or damaged file is one ``CheckpointError``
line.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
from scipy import ndimage

from kgn_bench.geometry import invert_pose, make_pose, matrix_from_quat_wxyz
from kgn_bench.giga import GRASP_REFERENCE_DEPTH, VOXEL_SIZE, WORKSPACE_ORIGIN
from kgn_bench.model.vgn_checkpoint import LoadedVGN, load_vgn_model
from kgn_bench.resources import weights_dir
from kgn_bench.tsdf import TSDFVolume

from .base import Candidates, Observation

__all__ = [
    "GIGA_BORDER",
    "GIGA_SELECTION",
    "VGN_SELECTION",
    "SelectionConfig",
    "VGNDetector",
    "VoxelGrasps",
    "grid_poses",
    "select_grasps",
    "vgn_weights_path",
]

GIGA_BORDER = (int(0.02 / VOXEL_SIZE), int(0.02 / VOXEL_SIZE), int(0.055 / VOXEL_SIZE))
"""GIGA's border mask in voxels, (2, 2, 7) on the 40³ grid: no grasp within ``int(limit / voxel)`` voxels of the
cube's x and y faces (limit 2 cm) or below ``int(5.5 cm / voxel)`` (5 mm above the table, which lies at 5 cm)."""


@dataclass(frozen=True)
class SelectionConfig:
    """VGN's post-processing of the predicted volumes (``select_grasps``); widths and sizes in voxels.

    ``threshold``: the quality a grasp needs. ``force_floor``: None = VGN (nothing below ``threshold``); a
    value = GIGA's ``--force``: qualities below it are dropped and, when no voxel reaches ``threshold``, the
    single best NMS maximum at or above the floor is returned alone. ``outside_threshold``: network-input value
    above which a voxel counts as outside (in front of) a surface for the surface mask. ``border``: voxels
    masked at the x, y faces (both ends) and the bottom (z), None = none. ``sigma``: the Gaussian smoothing of
    the quality (voxels, mode "nearest"). ``min_width`` / ``max_width``: predicted widths outside this range are
    dropped (1.33 / 9.33 voxels = 1 cm / 7 cm on the 7.5 mm grid). ``nms_size``: the ``maximum_filter`` window."""

    threshold: float = 0.9
    force_floor: float | None = 0.5
    outside_threshold: float = 0.1
    border: tuple[int, int, int] | None = GIGA_BORDER
    sigma: float = 1.0
    min_width: float = 1.33
    max_width: float = 9.33
    nms_size: int = 4

    def __post_init__(self) -> None:
        if not 0.0 <= self.threshold <= 1.0:
            raise ValueError(f"threshold must lie in [0, 1], got {self.threshold}")
        if self.force_floor is not None and not 0.0 <= self.force_floor <= self.threshold:
            raise ValueError(f"force_floor must lie in [0, threshold], got {self.force_floor}")
        if self.border is not None and (len(self.border) != 3 or min(self.border) < 0):
            raise ValueError(f"border must be three voxel counts ≥ 0, got {self.border}")
        if self.sigma < 0 or self.nms_size < 1 or not self.min_width <= self.max_width:
            raise ValueError("sigma must be ≥ 0, nms_size ≥ 1 and min_width ≤ max_width")


GIGA_SELECTION = SelectionConfig()
"""GIGA's evaluation (``sim_grasp_multiple.py --force --best``, ``out_th = 0.1``, border mask): the default."""
VGN_SELECTION = SelectionConfig(threshold=0.9, force_floor=None, outside_threshold=0.5, border=None)
"""The original VGN's selection (``vgn/detection.py``)."""


@dataclass(frozen=True)
class VoxelGrasps:
    """Selected grasps in voxel terms: ``index`` (N, 3) int voxel ``(i, j, k)``, ``quaternion`` (N, 4) unit
    (w, x, y, z) of ``R_grid_grasp``, ``width`` (N,) voxels, ``score`` (N,) smoothed quality, best first."""

    index: np.ndarray
    quaternion: np.ndarray
    width: np.ndarray
    score: np.ndarray

    def __len__(self) -> int:
        return len(self.index)


def select_grasps(quality: np.ndarray, rotation: np.ndarray, width: np.ndarray, tsdf_input: np.ndarray,
                  config: SelectionConfig = GIGA_SELECTION) -> VoxelGrasps:
    """VGN's selection on the network's volumes, in this order:

    1. ``q = gaussian_filter(quality, σ)`` (mode "nearest");
    2. surface mask: ``outside = x > o``, ``inside = 1e-3 < x < o`` on the network input ``x`` (``o`` the
       outside threshold), ``valid = binary_dilation(outside, 2 iterations, 6-connected, mask = ¬inside)``:
       the observed surface band and up to two voxels beyond it into space that is not behind a surface;
       ``q = 0`` where not valid;
    3. width mask: ``q = 0`` where ``width < min_width`` or ``width > max_width``;
    4. border mask (if any): ``q = 0`` on the ``border`` voxels of the x and y faces and the bottom;
    5. threshold: ``q = 0`` below ``threshold``; with ``force_floor``: ``q = 0`` below the floor, and when no
       voxel reaches ``threshold`` only the best maximum of step 6 is kept;
    6. NMS: keep the non-zero voxels equal to ``maximum_filter(q, nms_size)``;
    7. sort by ``q`` descending (ties in index order).

    ``quality``, ``width``, ``tsdf_input``: (R, R, R); ``rotation``: (4, R, R, R) (w, x, y, z). Arrays are not
    modified. Returns ``VoxelGrasps`` (quaternions renormalised)."""
    shape = quality.shape
    if len(shape) != 3 or width.shape != shape or tsdf_input.shape != shape or rotation.shape != (4, *shape):
        raise ValueError(f"select_grasps needs (R,R,R) volumes and a (4,R,R,R) rotation, got quality {shape}, "
                         f"rotation {rotation.shape}, width {width.shape}, tsdf {tsdf_input.shape}")
    c = config
    q = ndimage.gaussian_filter(np.asarray(quality, dtype=np.float64), sigma=c.sigma, mode="nearest")
    outside = tsdf_input > c.outside_threshold
    inside = (tsdf_input > 1e-3) & (tsdf_input < c.outside_threshold)
    valid = ndimage.binary_dilation(outside, iterations=2, mask=~inside)
    q[~valid] = 0.0
    q[(width < c.min_width) | (width > c.max_width)] = 0.0
    if c.border is not None:
        bx, by, bz = c.border
        if bx:
            q[:bx] = q[-bx:] = 0.0
        if by:
            q[:, :by] = q[:, -by:] = 0.0
        q[:, :, :bz] = 0.0
    best_only = False
    if c.force_floor is not None:
        q[q < c.force_floor] = 0.0
        best_only = not np.any(q >= c.threshold)
    if not best_only:
        q[q < c.threshold] = 0.0
    keep = (q == ndimage.maximum_filter(q, size=c.nms_size)) & (q > 0.0)
    index = np.argwhere(keep)
    score = q[keep]  # argwhere and boolean indexing both run in C order
    order = np.argsort(-score, kind="stable")
    if best_only:
        order = order[:1]
    index, score = index[order], score[order]
    i, j, k = index.T
    quat = np.asarray(rotation[:, i, j, k].T, dtype=np.float64).reshape(-1, 4)
    quat /= np.maximum(np.linalg.norm(quat, axis=1, keepdims=True), 1e-12)
    return VoxelGrasps(index.astype(np.int64), quat, np.asarray(width[i, j, k], dtype=np.float64), score)


def grid_poses(grasps: VoxelGrasps, voxel: float) -> np.ndarray:
    """(N, 4, 4) ``T_grid_grasp``: rotation from the quaternion, reference point at ``index · voxel`` (VGN's
    convention: no half-voxel offset), so the origin (the fingertips) ``GRASP_REFERENCE_DEPTH`` further along
    the approach (module docstring)."""
    poses = np.tile(np.eye(4), (len(grasps), 1, 1))
    if len(grasps):
        poses[:, :3, :3] = matrix_from_quat_wxyz(grasps.quaternion)
        poses[:, :3, 3] = grasps.index * voxel + GRASP_REFERENCE_DEPTH * poses[:, :3, 0]
    return poses


def vgn_weights_path(weights: str | Path | None = None) -> Path:
    """The weights file: ``weights`` if it is a path to a file (or ends in ``.pt``), else the shipped
    ``assets/weights/<weights>.pt``; the shipped ``vgn.pt`` when None."""
    if weights is None:
        return weights_dir() / "vgn.pt"
    if Path(weights).suffix == ".pt" or Path(weights).is_file():
        return Path(weights)
    return weights_dir() / f"{weights}.pt"


class VGNDetector:
    """VGN on a TSDF of GIGA's workspace cube (module docstring). ``timing`` holds the last call's seconds per
    stage: ``tsdf``, ``network`` and ``select``."""

    name = "vgn"
    privileged = False

    def __init__(self, weights: str | Path | None = None, model: LoadedVGN | None = None,
                 selection: SelectionConfig = GIGA_SELECTION, threads: int | None = None,
                 T_world_grid: np.ndarray | None = None) -> None:
        """``weights``: a name under assets/weights or a path (default the shipped ``vgn``), or an already
        loaded ``model``. ``T_world_grid``: where the grid's corner sits in the world (default GIGA's cube,
        ``make_pose(t=WORKSPACE_ORIGIN)``). ``threads``: torch's intra-op threads for the forward pass (None:
        leave them as they are)."""
        self.model = model if model is not None else load_vgn_model(vgn_weights_path(weights))
        self.selection = selection
        self.threads = threads
        self.T_world_grid = make_pose(t=WORKSPACE_ORIGIN) if T_world_grid is None else np.asarray(T_world_grid)
        self.timing: dict[str, float] = {}

    def reset(self, seed: list[int]) -> None:
        """Nothing to seed: the detector is deterministic."""

    def volume(self, observation: Observation) -> TSDFVolume:
        """The TSDF of one observation (NaN depth read as no reading); ``DetectorError`` if it is malformed."""
        depth = np.asarray(observation.depth)
        if np.issubdtype(depth.dtype, np.floating) and not np.all(np.isfinite(depth)):
            depth = np.where(np.isfinite(depth), depth, 0.0).astype(depth.dtype)
            observation = replace(observation, depth=depth)
        observation.validate()
        vol = TSDFVolume(self.model.grid, self.T_world_grid)
        vol.integrate(observation.depth, observation.intrinsics, observation.camera_pose)
        return vol

    def predict(self, tsdf_input: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The network's ``quality`` (R, R, R), ``rotation`` (4, R, R, R) (w, x, y, z) and ``width`` (R, R, R,
        voxels) for one network input (R, R, R)."""
        if self.threads:
            torch.set_num_threads(self.threads)
        net = self.model.net
        device = next(net.parameters()).device
        with torch.inference_mode():
            out = net(torch.from_numpy(np.ascontiguousarray(tsdf_input, dtype=np.float32))[None, None].to(device))
        return (out.quality[0, 0].float().cpu().numpy(), out.rotation[0].float().cpu().numpy(),
                out.width[0, 0].float().cpu().numpy())

    def detect(self, observation: Observation) -> Candidates:
        self.timing = {}
        t = time.perf_counter()
        tsdf_input = self.volume(observation).network_input()
        self.timing["tsdf"] = time.perf_counter() - t
        t = time.perf_counter()
        quality, rotation, width = self.predict(tsdf_input)
        self.timing["network"] = time.perf_counter() - t
        t = time.perf_counter()
        grasps = select_grasps(quality, rotation, width, tsdf_input, self.selection)
        voxel = self.model.grid.voxel
        T_cam_grid = invert_pose(observation.camera_pose) @ self.T_world_grid
        poses = T_cam_grid @ grid_poses(grasps, voxel)
        self.timing["select"] = time.perf_counter() - t
        return Candidates(poses, grasps.width * voxel, grasps.score, np.full(len(grasps), np.nan))
