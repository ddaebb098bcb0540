"""The random detector: the harness's floor.

It picks observed points above the table top (the one fact it uses besides the image: the world z of
the table, which any tabletop system knows), and at each puts a grasp whose approach is uniform on the
downward hemisphere, turned uniformly about the approach, sunk ``sink`` m into the surface, with a width
uniform in ``width_range``. Confidences are uniform in [0, 1]; no reprojection error.

``count`` grasps per capture, 1 by default: the floor is one blind guess per attempt. The selector still
vets it (a guess that would collide or enclose nothing is not executed: the attempt fails as
``no_candidate``), but it has nothing to choose from. With many guesses the selector's checks pick the
feasible ones and its levelling and centring fix them up: that measures the selector as a sample-and-filter
planner, not the floor: ``--detector kgn_bench.detectors.random:sample_and_filter`` runs it (the results,
docs/results.md).
"""

from __future__ import annotations

import numpy as np

from kgn_bench.geometry import frame_from_xz, invert_pose, make_pose

from .base import Candidates, Observation

__all__ = ["RandomDetector", "sample_and_filter"]


class RandomDetector:
    name = "random"
    privileged = False

    def __init__(self, count: int = 1, sink: float = 0.015, width_range: tuple[float, float] = (0.02, 0.12),
                 min_height: float = 0.005) -> None:
        self.count = count
        self.sink = sink
        self.width_range = width_range
        self.min_height = min_height
        self._rng = np.random.default_rng(0)

    def reset(self, seed: list[int]) -> None:
        self._rng = np.random.default_rng([*seed, 0x5EED])

    def detect(self, observation: Observation) -> Candidates:
        observation.validate()
        pts = observation.points_world(stride=2)
        pts = pts[pts[:, 2] > self.min_height]
        if len(pts) == 0:
            return Candidates.empty()
        rng = self._rng
        n = self.count
        centres = pts[rng.integers(len(pts), size=n)]
        # approach uniform on the lower hemisphere: z component uniform in [−1, 0]
        cz = -rng.uniform(0.0, 1.0, n)
        phi = rng.uniform(0.0, 2 * np.pi, n)
        s = np.sqrt(1.0 - cz**2)
        x = np.stack([s * np.cos(phi), s * np.sin(phi), cz], axis=1)
        poses = np.empty((n, 4, 4))
        for k in range(n):
            helper = np.array([0.0, 0.0, 1.0]) if abs(x[k, 2]) < 0.9 else np.array([1.0, 0.0, 0.0])
            z = np.cross(x[k], helper)
            z /= np.linalg.norm(z)
            a = rng.uniform(0.0, 2 * np.pi)
            z = np.cos(a) * z + np.sin(a) * np.cross(x[k], z)
            R = frame_from_xz(x[k], z)
            poses[k] = make_pose(R, centres[k] + self.sink * x[k])
        widths = rng.uniform(*self.width_range, n)
        conf = rng.uniform(0.0, 1.0, n)
        cam = invert_pose(observation.camera_pose) @ poses
        return Candidates(cam, widths, conf, np.full(n, np.nan))


def sample_and_filter() -> RandomDetector:
    """64 random guesses per capture (named ``random64``): what the selector's checks, levelling and centring
    make of blind samples, a measure of the selector rather than the floor."""
    det = RandomDetector(count=64)
    det.name = "random64"
    return det
