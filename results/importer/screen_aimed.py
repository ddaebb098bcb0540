"""Which imported objects the aimed-candidate rule would change (issue 44): those with a rest pose in which fewer
than ``objects.coverage.REST_GRASPS`` of the import's uniform candidates are executable.

    .venv/bin/python results/importer/screen_aimed.py LIBRARY [NAME ...]

Recomputes each object's uniform candidates as its import drew them (the manifest's seed and sampling
settings, on the stored visual mesh: a few candidates differ from the import's after the mesh file's
round trip) and prints the executable count per rest pose of every object below the mark. Objects imported
before the rule whose names it prints get other verified grasps when imported again.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import trimesh

from kgn_bench.objects.coverage import REST_GRASPS, executable
from kgn_bench.shapes.grasp_sampling import SamplingConfig, sample_antipodal_grasps


def screen(root: Path, names: list[str]) -> list[str]:
    affected = []
    for name in names:
        manifest = json.loads((root / name / "object.json").read_text())
        if "aimed" in manifest["grasps"]:
            continue  # imported with the rule
        settings = manifest["import"]
        mesh = trimesh.load(root / name / "visual.ply", process=False)
        rng = np.random.default_rng(settings["seed"])
        poses, widths = sample_antipodal_grasps(mesh, rng, SamplingConfig(**settings["sampling"]))
        counts = executable(mesh, [r["R"] for r in manifest["rest_poses"]], poses, widths).sum(axis=1)
        if (counts < REST_GRASPS).any():
            affected.append(name)
            print(f"{name}: {len(poses)} candidates, executable per rest pose {counts.tolist()}", flush=True)
    return affected


if __name__ == "__main__":
    library = Path(sys.argv[1])
    chosen = sys.argv[2:] or sorted(p.parent.name for p in library.glob("*/object.json"))
    found = screen(library, chosen)
    print(f"{len(found)} of {len(chosen)} objects would change: {' '.join(found)}")
