"""The importer's fallback: surfaces that repair cannot close become watertight voxel solids, close to the input."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from kgn_bench.objects import remesh
from kgn_bench.objects.importer import UnclosedSurfaceError, repair_mesh
from kgn_bench.objects.remesh import MAX_CELLS, voxel_remesh
from kgn_bench.shapes.mesh_object import ObjectError


def walled_box() -> trimesh.Trimesh:
    """Two 4 cm cubes sharing a face that the file keeps as an inner wall: its 4 edges have 3 faces each."""
    a, b = trimesh.creation.box((0.04, 0.04, 0.04)), trimesh.creation.box((0.04, 0.04, 0.04))
    a.apply_translation((-0.02, 0.0, 0.0))
    b.apply_translation((0.02, 0.0, 0.0))
    m = trimesh.util.concatenate([a, b])
    m.merge_vertices()
    return m


def moebius_band(n: int = 40, radius: float = 0.05, half_width: float = 0.01) -> trimesh.Trimesh:
    """A one-sided open sheet: no cap can close it."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    centre = np.stack([radius * np.cos(t), radius * np.sin(t), np.zeros(n)], axis=1)
    across = np.stack([np.cos(t) * np.cos(t / 2), np.sin(t) * np.cos(t / 2), np.sin(t / 2)], axis=1)
    vertices = np.stack([centre - half_width * across, centre + half_width * across], axis=1).reshape(-1, 3)
    faces = []
    for i in range(n):
        j = (i + 1) % n
        b0, b1 = (2 * j, 2 * j + 1) if j else (1, 0)  # the half twist joins the ends crosswise
        faces += [[2 * i, b0, 2 * i + 1], [2 * i + 1, b0, b1]]
    return trimesh.Trimesh(vertices, np.array(faces), process=False)


def test_an_inner_wall_is_refused_by_repair_and_remeshed_within_a_voxel():
    mesh = walled_box()
    with pytest.raises(UnclosedSurfaceError, match="4 edges shared by more than two faces"):
        repair_mesh(mesh)
    r = voxel_remesh(mesh, 0.002)
    assert r.thickened == 0  # a solid's faces and corners are not walls
    assert r.mesh.is_watertight and r.mesh.is_winding_consistent and r.mesh.body_count == 1
    assert r.pitch == 0.002 and r.deviation <= r.pitch
    assert r.mesh.volume == pytest.approx(2 * 0.04**3, rel=0.15)
    np.testing.assert_allclose(r.mesh.extents, [0.08, 0.04, 0.04], atol=2 * r.pitch)


def test_an_open_sheet_becomes_a_wall():
    band = moebius_band()
    with pytest.raises(UnclosedSurfaceError, match="80 open edges"):
        repair_mesh(band)
    r = voxel_remesh(band, 0.002)
    assert r.thickened > 0 and r.mesh.is_watertight and r.mesh.body_count == 1
    assert r.mesh.euler_number == 0  # a thickened Möbius band is a solid ring: genus 1
    assert 0.002 < r.deviation < 0.002 * 2.5  # about the wall's half thickness, more at its edges
    assert r.mesh.volume == pytest.approx(band.area * 2 * 0.002, rel=0.3)  # a wall two voxels thick


def test_a_fine_pitch_is_coarsened_to_the_grid_limit(monkeypatch):
    monkeypatch.setattr(remesh, "MAX_CELLS", 46)
    r = voxel_remesh(walled_box(), 1e-5)
    assert r.pitch == pytest.approx(0.08 / (46 - 2 * remesh.MARGIN))
    assert r.mesh.is_watertight and MAX_CELLS > 46


def test_nothing_to_remesh_is_one_error_line():
    empty = trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=int))
    with pytest.raises(ObjectError, match="no finite triangles"):
        voxel_remesh(empty, 0.002)
    with pytest.raises(ValueError, match="pitch"):
        voxel_remesh(walled_box(), 0.0)
