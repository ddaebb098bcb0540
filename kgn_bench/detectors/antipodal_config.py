"""The settings of the antipodal detector (``kgn_bench.detectors.antipodal``), one frozen dataclass."""

from __future__ import annotations

from dataclasses import dataclass

from kgn_bench.gripper import GRIPPER

__all__ = ["AntipodalConfig"]


@dataclass(frozen=True)
class AntipodalConfig:
    """The settings of ``AntipodalDetector`` (module docstring, steps 1-7). Lengths in metres, heights along
    world z above the table plane z = 0, grasp-axis coordinates in the gripper frame of ``kgn_bench.grasp``
    (x approach, z closing)."""

    stride: int = 2
    """Pixel step of the point cloud (every ``stride``-th row and column of the depth image; step 1)."""
    seeds: int = 160
    """Object points drawn as seeds (step 3); fewer where fewer points have coherent normals."""
    approaches: int = 5
    """Family A frames per seed: approach directions spread over ±70° around the most downward one."""
    closings: int = 6
    """Family B frames per seed: closing axes spread over 180° around the approach along −normal."""
    neighbours: int = 900
    """At most this many random cloud points make a seed's neighbourhood (step 4)."""
    radius: float = 0.2
    """... all of them within this distance of the seed."""
    min_height: float = 0.005
    """A point higher than this above the table is an object point (seeds, extents, scores)."""
    collision_height: float = 0.002
    """A point higher than this above the table is an obstacle point (the clearance check, step 5)."""
    depth: float = GRIPPER.finger_length - 0.02
    """The fingertips go this far past the first surface along the approach (less near the table)."""
    min_depth: float = 0.004
    """... and at least this far, or the frame is rejected."""
    margin: float = 0.008
    """Per side between the object's extent and an open finger: width = extent + 2 · margin."""
    min_width: float = 0.02
    """The narrowest width returned."""
    table_clearance: float = 0.004
    """The lowest world z any gripper box (fingers, palm, wrist, swept back the pre-grasp) may reach."""
    push: float = 0.01
    """How far the harness may move a grasp on along its approach; the clearance check sweeps this far."""
    cone_deg: float = 20.0
    """Friction cone half-angle in degrees: antipodality scores 0 at twice this angle (step 6)."""
    min_enclosed: int = 6
    """Fewest object points between the fingers (also the fewest object points for any detection)."""
    top: int = 300
    """Most candidates returned, best first after duplicate removal (step 7)."""
    chunk: int = 384
    """Frames evaluated at once (bounds the memory of the (frames, neighbours) arrays)."""
