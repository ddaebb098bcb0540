"""Part builders: geoms and meshes placed where asked, capsules watertight and convex."""

import numpy as np
import pytest

from kgn_bench.geometry import matrix_from_quat_wxyz
from kgn_bench.shapes.household.parts import box, concatenate, cylinder, cylinder_mesh, tapered_capsule, z_to


def test_z_to_turns_z_onto_the_direction():
    for d in ([1.0, 2.0, 3.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]):
        R = z_to(np.array(d))
        np.testing.assert_allclose(R @ [0.0, 0.0, 1.0], np.array(d) / np.linalg.norm(d), atol=1e-12)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)


def test_cylinder_and_box_geoms():
    g = cylinder((0.0, 0.0, 0.0), (0.1, 0.0, 0.0), 0.01)
    assert g.kind == "cylinder" and g.size == pytest.approx((0.01, 0.05)) and g.pos == pytest.approx((0.05, 0, 0))
    np.testing.assert_allclose(matrix_from_quat_wxyz(np.array(g.quat)) @ [0, 0, 1], [1, 0, 0], atol=1e-12)
    b = box((0.0, 0.1, 0.0), (0.02, 0.04, 0.06))
    assert b.kind == "box" and b.size == pytest.approx((0.01, 0.02, 0.03)) and b.quat == (1.0, 0.0, 0.0, 0.0)


def test_tapered_capsule_is_a_watertight_convex_hull_of_its_spheres():
    m = tapered_capsule(np.zeros(3), 0.02, np.array([0.0, 0.0, 0.1]), 0.01)
    assert m.is_watertight and m.is_convex
    lo, hi = m.bounds
    np.testing.assert_allclose([lo[2], hi[2]], [-0.02, 0.11], atol=1e-3)
    both = concatenate([m, cylinder_mesh((0.2, 0.0, 0.0), (0.3, 0.0, 0.0), 0.01)])
    assert both.is_watertight and len(both.faces) > len(m.faces)
