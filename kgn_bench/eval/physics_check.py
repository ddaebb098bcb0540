"""``kgn-bench eval physics``: do a detector's predicted grasps hold the object, judged by physics, not labels.

The vision metrics (``eval.vision``) count a prediction as right when it lies within 1 cm / 20° of a labelled
grasp, so they depend on how densely the labels cover the grasps that would work. That is fine for the
primitives' dense closed-form families, and it understates a detector on an imported mesh, whose labels
are at most a few hundred physics-verified grasps scattered over every direction. This check needs no labels.

For each test view, the ``top_k`` highest-scoring predictions (world frame) are each assigned to the object of
their nearest labelled grasp (as ``eval.errors`` does), taken into that object's frame,
``T_obj_grasp = T_world_obj⁻¹ · T_world_grasp``, and run through the labeller's physics check
(``sim.grasp_verify.verify_grasps``: the object alone with the benchmark's gripper, close, hold, shake). The
figure is the share that held, per ``eval.vision.SHAPES`` column and overall, beside the share within 1 cm /
20° of a label (the GSR of the same predictions). Like the labels' own check it ignores the table and the
other objects; the closed loop is where those count.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from kgn_bench.geometry import invert_pose
from kgn_bench.grasp import GraspSet
from kgn_bench.progress import Progress
from kgn_bench.shapes import shape_from_dims
from kgn_bench.sim.grasp_verify import verify_grasps
from kgn_bench.types import Candidates, Observation

from .views import detector_call, iter_views
from .vision import SHAPES, THRESHOLDS, nearest_grasps, shape_column

__all__ = ["physics_success", "to_markdown"]


def physics_success(detect: Callable[[Observation], Candidates], data_dir: Path, split: str = "test",
                    views: int | None = None, top_k: int = 10, progress: bool = True) -> dict:
    """Counts per shape column (module doc): ``{"all" | shape: {"checked", "held", "labelled"}}``."""
    run = detector_call(detect)
    total, items = iter_views(data_dir, split, views)
    counts = {name: {"checked": 0, "held": 0, "labelled": 0} for name in ("all", *SHAPES)}
    shapes: dict[tuple, object] = {}
    bar = Progress(total, f"eval physics {split}", unit="images", enabled=progress)
    for item in items:
        cands = run(item)
        grasps = GraspSet.concatenate(list(item.gt))
        bar.update(extra=f"held {100 * counts['all']['held'] / max(counts['all']['checked'], 1):.0f}%")
        if len(cands) == 0 or len(grasps) == 0:
            continue
        keep = np.argsort(-cands.confidences, kind="stable")[:top_k]
        world = cands.world_poses(item.observation.camera_pose)[keep]
        widths = cands.widths[keep]
        owner = np.repeat(np.arange(len(item.gt)), [len(g) for g in item.gt])
        _, _, nearest, labelled = nearest_grasps(world, grasps)
        target = owner[nearest]
        for k in np.unique(target):  # one physics rig per object and view, all its predictions through it
            obj, mine = item.objects[k], np.flatnonzero(target == k)
            key = (obj.type, repr(sorted(obj.dims.items())))
            if key not in shapes:
                shapes[key] = shape_from_dims(obj.type, obj.dims)
            held = verify_grasps(shapes[key], invert_pose(obj.pose)[None] @ world[mine], widths[mine])
            for name in ("all", shape_column(obj.type)):
                counts[name]["checked"] += len(mine)
                counts[name]["held"] += int(held.sum())
                counts[name]["labelled"] += int(labelled[mine].sum())
    bar.close()
    return counts


def to_markdown(counts: dict, label: str) -> str:
    """A table of the counts: per column, predictions checked, the share that held, the share near a label."""
    rows = [f"Physics check of the top predictions of {label} (object alone with the gripper; "
            f"{THRESHOLDS[0].label} for 'near a label').", "",
            "| objects | predictions checked | held in physics | within 1 cm / 20° of a label |",
            "|---|---:|---:|---:|"]
    for name, c in counts.items():
        if c["checked"]:
            rows.append(f"| {name} | {c['checked']} | {100 * c['held'] / c['checked']:.1f} % | "
                        f"{100 * c['labelled'] / c['checked']:.1f} % |")
    return "\n".join(rows) + "\n"
