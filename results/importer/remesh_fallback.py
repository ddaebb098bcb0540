"""The importer's voxel fallback on every mesh of pybullet_data that repair cannot close (issue 44, item 1).

Each mesh is scaled to a 10 cm largest extent (as ``kgn-bench objects add --size 0.1`` would) and rebuilt by
``objects.remesh.voxel_remesh`` at ``REMESH_PITCH``. Writes ``remesh_fallback.md`` (why repair refused it,
the time, the faces and the largest deviation from the file's surface) and ``remesh_fallback.png`` (four of
them, the file's surface beside the remesh).

    python results/importer/remesh_fallback.py
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pybullet_data
import trimesh

from kgn_bench.objects.importer import MAX_FACES, UnclosedSurfaceError, _read, repair_mesh
from kgn_bench.objects.remesh import REMESH_PITCH, voxel_remesh

OUT = Path(__file__).parent
SIZE = 0.10
SHOWN = ("mug_col.obj", "lego.obj", "hand.obj", "l_finger.stl")


def unclosable() -> list[tuple[Path, trimesh.Trimesh, str]]:
    root = Path(pybullet_data.getDataPath())
    files = sorted([p for p in root.rglob("*.obj") if "random_urdfs" not in p.parts] + list(root.rglob("*.stl")))
    found = []
    for p in files:
        try:
            mesh = _read(p)
            if len(mesh.faces) > MAX_FACES:
                continue
            repair_mesh(mesh, p.name)
        except UnclosedSurfaceError as e:
            found.append((p.relative_to(root), mesh, str(e).split(": ", 1)[1]))
        except Exception:  # other refusals (no triangles, ...) are not the fallback's
            continue
    return found


def draw(ax, mesh: trimesh.Trimesh, title: str) -> None:
    v = mesh.vertices - mesh.bounds.mean(axis=0)
    tri = v[mesh.faces]
    light = np.array([0.4, -0.5, 0.77])
    shade = 0.35 + 0.65 * np.clip(np.abs(mesh.face_normals @ light), 0, 1)
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    ax.add_collection3d(Poly3DCollection(tri, facecolors=plt.cm.Greys(0.25 + 0.6 * shade), linewidths=0))
    r = np.abs(v).max()
    ax.set(xlim=(-r, r), ylim=(-r, r), zlim=(-r, r), title=title)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=25, azim=-60)
    ax.set_axis_off()


def main() -> None:
    warnings.filterwarnings("ignore")
    rows, shown = [], []
    for rel, mesh, reason in unclosable():
        scale = SIZE / float(mesh.extents.max())
        t = time.perf_counter()
        r = voxel_remesh(mesh, REMESH_PITCH / scale, origin=rel.name)
        seconds = time.perf_counter() - t
        rows.append(f"| `{rel}` | {reason} | {seconds:.1f} | {len(r.mesh.faces)} | {r.deviation * scale * 1000:.1f} |")
        if rel.name in SHOWN and rel.name not in [s[0] for s in shown]:
            shown.append((rel.name, mesh, r.mesh, r.deviation * scale * 1000))
    lines = ["# The importer's voxel fallback on pybullet_data",
             "",
             f"Every mesh of `pybullet_data` (outside `random_urdfs`) that repair leaves open or non-manifold, scaled "
             f"to {SIZE * 100:.0f} cm and remeshed at {REMESH_PITCH * 1000:.0f} mm "
             "(`python results/importer/remesh_fallback.py`). Deviation: the largest distance from the new "
             "surface to the file's.",
             "", f"{len(rows)} meshes, all remeshed watertight.", "",
             "| mesh | why repair refused it | seconds | faces | deviation (mm) |", "| --- | --- | --- | --- | --- |",
             *rows]
    (OUT / "remesh_fallback.md").write_text("\n".join(lines) + "\n")
    fig = plt.figure(figsize=(4 * len(shown), 7.5))
    for k, (name, before, after, dev) in enumerate(shown):
        draw(fig.add_subplot(2, len(shown), k + 1, projection="3d"), before, f"{name}: the file")
        draw(fig.add_subplot(2, len(shown), len(shown) + k + 1, projection="3d"), after,
             f"remeshed, within {dev:.1f} mm")
    fig.tight_layout()
    fig.savefig(OUT / "remesh_fallback.png", dpi=90)
    print(f"wrote {OUT / 'remesh_fallback.md'} ({len(rows)} meshes) and remesh_fallback.png")


if __name__ == "__main__":
    main()
