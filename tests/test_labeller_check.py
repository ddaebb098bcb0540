"""The labeller against the closed-form families: the depth-free match, and a real run on one primitive."""

from __future__ import annotations

import math

import numpy as np

from kgn_bench.geometry import make_pose, rot_x
from kgn_bench.objects.labeller_check import check_labeller, depth_free_matches, format_table


def test_depth_free_match_ignores_the_approach_offset_only():
    b = make_pose()[None]
    deeper = make_pose(t=np.array([0.05, 0.0, 0.0]))  # 5 cm along the approach x: same grasp line
    aside = make_pose(t=np.array([0.0, 0.015, 0.0]))  # 1.5 cm sideways
    flipped = make_pose(rot_x(np.pi))  # the jaws swapped: the same grasp
    turned = make_pose(rot_x(np.deg2rad(30.0)))
    a = np.stack([deeper, aside, flipped, turned])
    assert depth_free_matches(a, b, 0.01, math.radians(20.0)).tolist() == [True, False, True, False]


def test_labeller_on_a_cuboid_agrees_with_its_family():
    """Every closed-form cuboid grasp holds in physics and passes the labeller's test; the labeller's own
    grasps include ones outside the family (approaches off the face normals), which held in physics."""
    (r,) = check_labeller(["cuboid"], verify=16, hulls=2, control=8)
    assert r.family_held == r.family_checked > 0 and r.recall == 1.0
    assert r.labelled >= 8 and 0 < r.labelled_in_family <= r.labelled
    assert r.control == 8 and r.control_held < r.control  # random grasps mostly fail: the check can say no
    assert "| cuboid |" in format_table([r])
