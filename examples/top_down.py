"""A complete detector in a dozen lines: grasp the highest observed point from straight above.

Run it in the benchmark without touching kgn_bench:  PYTHONPATH=examples kgn-bench run tasks/single_object.toml
--detector top_down:TopDown --workers 2
"""

import numpy as np

from kgn_bench.detectors import Candidates, Observation

DOWN = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])  # approach x = world −z, closing z = world +y


class TopDown:
    name, privileged = "top_down", False

    def reset(self, seed: list[int]) -> None:  # seed any randomness here (run seed, trial index)
        pass

    def detect(self, obs: Observation) -> Candidates:
        points = obs.points_world(stride=2)  # (N, 3) world points back-projected from the depth image
        points = points[points[:, 2] > 0.005]  # drop the table (its top is the plane z = 0)
        if len(points) == 0:
            return Candidates.empty()
        grasp = np.eye(4)
        grasp[:3, :3] = DOWN
        grasp[:3, 3] = points[points[:, 2].argmax()] - [0.0, 0.0, 0.02]  # fingertips 2 cm below the top
        in_camera = np.linalg.inv(obs.camera_pose) @ grasp  # candidates are T_cam_grasp
        return Candidates(in_camera[None], widths=np.array([0.08]), confidences=np.array([1.0]),
                          reprojection_errors=np.array([np.nan]))
