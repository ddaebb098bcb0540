"""The importer's fallback for a surface that repair cannot close: a voxel solid and its level set.

A mesh that stays open or non-manifold after ``importer.repair_mesh`` (edges shared by more than two faces,
open parts that manifold3d cannot read as solids, a cup modelled as a single sheet) is rebuilt as the
boundary of a solid made of voxels of side ``h`` (``pitch``):

1. **shell**: every voxel that the input surface passes through (trimesh's subdivision voxeliser, which needs
   no inside or outside, so it takes any triangle soup);
2. **solid**: the shell closed morphologically (``close`` iterations of a 6-neighbour dilation then erosion,
   sealing cracks up to about ``2 · close · h``; one by default, so that a real gap, a mug's handle, stays)
   and its enclosed cavities filled (``scipy.ndimage.binary_fill_holes``). A closed surface becomes its
   filled inside. An open sheet (a cup modelled as one surface, a fin) stays a wall one or two voxels thick,
   and such thin parts (solid voxels more than two voxels, in the chessboard metric, from any voxel at least
   two deep) grow by one voxel on each side: the wall is then about three voxels thick and the level set does
   not break through it where it runs diagonally to the grid, while a solid's own faces and corners stay
   where they are;
3. **signed distance** in voxel units, positive inside: ``s = EDT(solid) − ½`` inside and
   ``−(EDT(outside) − ½)`` outside, smoothed by a Gaussian of ``SMOOTHING`` voxels (the voxels' staircase
   would otherwise stay in the surface);
4. **surface**: the level set ``s = LEVEL`` (½: through the centres of the outermost solid voxels, which the
   input surface crosses) of the trilinear interpolant of ``s`` by manifold3d's marching tetrahedra
   (``Manifold.level_set``), which is watertight and 2-manifold by construction, then simplified within
   ``h / 2`` (half the faces of ``h / 4`` at the same deviation, which CoACD then decomposes faster).

Frames: the result is in the input's frame and units (the voxel grid is axis-aligned there, its corner at
the input's bounds minus a margin of ``MARGIN`` voxels). The importer passes ``h = REMESH_PITCH / scale``, so
that ``h`` is ``REMESH_PITCH`` in the object's final metres: a fifth of the finger's thickness, well below what
decides whether a grasp holds. The result's ``deviation`` is the largest distance from a point of the new
surface to the input surface (``DEVIATION_SAMPLES`` points sampled on the new one): every part of the object
as imported lies within it of what the file describes. The other direction is not a defect: inner walls and
the inside of a thickened sheet are meant to disappear. On the 37 meshes of ``pybullet_data`` that repair
cannot close (robot links, a mug's collision mesh, a LEGO brick, scaled to 10 cm) it is 1.6-4.0 mm, one to
two voxels: a surface crossing a voxel can pass up to √3/2 of a voxel from its centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import manifold3d
import numpy as np
import trimesh
from scipy import ndimage

from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.mesh_object import ObjectError

__all__ = ["DEVIATION_SAMPLES", "LEVEL", "MARGIN", "MAX_CELLS", "REMESH_PITCH", "SMOOTHING", "Remeshed",
           "voxel_remesh"]

_CUBE = np.ones((3, 3, 3), dtype=bool)

REMESH_PITCH = GRIPPER.finger_thickness / 5.0
"""Voxel side (m, in the object's final size) of the fallback: 2 mm for the 1 cm finger."""
MARGIN = 3
"""Empty voxels around the input's bounds (room for the closing and the level set)."""
MAX_CELLS = 160
"""Voxels along the longest axis at most; a finer ``pitch`` is coarsened to fit (and reported)."""
SMOOTHING = 0.6
"""σ (voxels) of the Gaussian that smooths the signed distance before the level set."""
LEVEL = 0.5
"""The level (voxels) the surface is extracted at: through the centres of the outermost solid voxels."""
DEVIATION_SAMPLES = 4000
"""Points sampled on each surface to measure the deviation."""


@dataclass(frozen=True)
class Remeshed:
    """A fallback remesh: the watertight ``mesh`` (input frame and units), the ``pitch`` used (input units),
    the largest sampled distance from it to the input surface (``deviation``, input units), how many voxels
    the solid holds (``voxels``) and how many of them thickened thin walls (``thickened``)."""

    mesh: trimesh.Trimesh
    pitch: float
    deviation: float
    voxels: int
    thickened: int


def _solid(mesh: trimesh.Trimesh, pitch: float, close: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Steps 1-2: the solid's occupancy (X, Y, Z bool), the grid's corner (input units; voxel ``(i, j, k)`` is
    centred at ``corner + (i, j, k) · pitch``) and the number of voxels added to thin walls."""
    corner = mesh.bounds[0] - MARGIN * pitch
    shape = np.ceil((mesh.bounds[1] - corner) / pitch).astype(int) + MARGIN + 1
    shell = np.zeros(shape, dtype=bool)
    points = mesh.voxelized(pitch, method="subdivide").points  # centres of the voxels the surface crosses
    idx = np.clip(np.round((points - corner) / pitch).astype(int), 0, shape - 1)
    shell[tuple(idx.T)] = True
    closed = ndimage.binary_closing(shell, iterations=close, border_value=0) | shell if close else shell
    solid = ndimage.binary_fill_holes(closed)
    core = ndimage.distance_transform_cdt(solid, metric="chessboard") >= 2
    thin = solid & ~ndimage.binary_dilation(core, structure=_CUBE, iterations=2)
    walls = ndimage.binary_dilation(thin) & ~solid
    return solid | walls, corner, int(walls.sum())


def _signed_distance(solid: np.ndarray) -> np.ndarray:
    """Step 3, in voxels, positive inside."""
    inside = ndimage.distance_transform_edt(solid)
    outside = ndimage.distance_transform_edt(~solid)
    return np.where(solid, inside - 0.5, -(outside - 0.5))


def _level_set(sdf: np.ndarray) -> trimesh.Trimesh:
    """Step 4: the zero level of the trilinear interpolant of ``sdf`` (grid units: voxel ``(i, j, k)`` at the
    point ``(i, j, k)``)."""
    nx, ny, nz = sdf.shape
    flat = sdf.astype(float).ravel().tolist()  # Python floats: the callback runs once per lattice point
    sy, sx = nz, ny * nz

    def f(x: float, y: float, z: float) -> float:
        if not (0.0 <= x < nx - 1 and 0.0 <= y < ny - 1 and 0.0 <= z < nz - 1):
            return -1.0
        i, j, k = int(x), int(y), int(z)
        u, v, w = x - i, y - j, z - k
        o = i * sx + j * sy + k
        c00 = flat[o] * (1 - w) + flat[o + 1] * w
        c01 = flat[o + sy] * (1 - w) + flat[o + sy + 1] * w
        c10 = flat[o + sx] * (1 - w) + flat[o + sx + 1] * w
        c11 = flat[o + sx + sy] * (1 - w) + flat[o + sx + sy + 1] * w
        return (c00 * (1 - v) + c01 * v) * (1 - u) + (c10 * (1 - v) + c11 * v) * u

    solid = manifold3d.Manifold.level_set(f, [0.0, 0.0, 0.0, nx - 1.0, ny - 1.0, nz - 1.0], 1.0, LEVEL)
    solid = solid.simplify(0.5)
    out = solid.to_mesh()
    # process=False: manifold's vertices are already shared; merging coincident ones would glue the two sides of
    # a thin wall where they touch and break the 2-manifold
    return trimesh.Trimesh(np.asarray(out.vert_properties)[:, :3], np.asarray(out.tri_verts), process=False)


def _deviation(result: trimesh.Trimesh, source: trimesh.Trimesh, seed: int) -> float:
    """The largest distance from points sampled on ``result`` to the surface ``source`` (input units)."""
    points, _ = trimesh.sample.sample_surface(result, DEVIATION_SAMPLES, seed=seed)
    _, distance, _ = trimesh.proximity.closest_point(source, points)
    return float(distance.max())


def voxel_remesh(mesh: trimesh.Trimesh, pitch: float, close: int = 1, origin: str = "mesh", seed: int = 0
                 ) -> Remeshed:
    """The watertight remesh of ``mesh`` at voxel side ``pitch`` (input units; module docstring), with
    ``close`` closing iterations. ``ObjectError`` (naming ``origin``) when the input is empty or not finite,
    or when the solid holds no voxel."""
    if len(mesh.faces) == 0 or not np.all(np.isfinite(mesh.vertices)):
        raise ObjectError(f"{origin}: no finite triangles to remesh")
    if not pitch > 0:
        raise ValueError(f"pitch must be positive, got {pitch}")
    pitch = max(pitch, float(mesh.extents.max()) / (MAX_CELLS - 2 * MARGIN))
    soup = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    solid, corner, thickened = _solid(soup, pitch, close)
    if not solid.any():
        raise ObjectError(f"{origin}: the surface encloses nothing, even as a {pitch:.3g}-voxel solid")
    result = _level_set(ndimage.gaussian_filter(_signed_distance(solid), SMOOTHING))
    result.apply_scale(pitch)
    result.apply_translation(corner)
    trimesh.repair.fix_normals(result)
    if not result.is_watertight or result.volume <= 0:
        raise ObjectError(f"{origin}: the voxel remesh did not give a closed surface")
    return Remeshed(result, pitch, _deviation(result, soup, seed), int(solid.sum()), thickened)
