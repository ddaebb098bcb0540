"""``kgn-bench objects check-labeller``: the mesh labeller against the primitives' closed-form grasp families.

For each primitive shape (one seeded instance), two grasp sets in the shape's object frame:

* **family**: the closed-form grasps (``Shape.grasps``), each run through the same physics check
  (``sim.grasp_verify``) with the primitive's own collision geoms;
* **labelled**: the shape's triangle mesh exported to STL and imported exactly as a user's mesh is
  (``objects.importer.import_mesh``: repair, CoACD, antipodal sampling, physics check), mapped back to the
  shape's frame (the importer moves the origin to the centre of mass).

The two conventions differ in grasp depth only: a family fixes how deep the fingertips go (e.g. 2 cm into a
cuboid's face), the labeller puts the fingertip midpoint at the contacts' midpoint. So the comparison ignores
the offset along the approach axis: grasp ``a`` agrees with grasp ``b`` when

    d_⊥ = ‖(t_a − t_b) − ((t_a − t_b)·x_b) x_b‖ < ``translation``   and   d_R(R_a, R_b) < ``rotation``

with ``x_b`` the approach axis of ``b`` and ``d_R`` the rotation error under the jaws' 180° symmetry
(``grasp.grasp_rotation_error``). Figures per shape:

* ``precision``: the share of labelled grasps that agree with some family grasp (a dense family, so
  sampling gaps do not count against the labeller);
* ``recall``: the share of the family grasps that hold in physics which the labeller's geometric test
  (``shapes.grasp_sampling.antipodal_accepts``, what every labelled candidate passed) also accepts. Asking the
  test, not the labeller's random sample, keeps the figure free of sampling density;
* the disagreements, and which side physics takes: a labelled grasp outside the family held by construction
  (the family is incomplete there); a family grasp that fails in physics is wrong; a family grasp that holds
  but the test rejects is a miss of the labeller (its friction cone or its clearance); a failed family grasp
  that the test accepts shows why the physics check is needed after it.
* a **control** that shows both checks can say no: ``control`` random grasps (origin uniform in the shape's
  bounding box, rotation uniform, the labeller's width for its contacts or the full opening), each run
  through physics and the labeller's test; their agreement is the share of random grasps on which the two
  verdicts match.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from kgn_bench.errors import InputError
from kgn_bench.geometry import make_pose
from kgn_bench.grasp import grasp_rotation_error
from kgn_bench.objects.importer import ImportConfig, import_mesh
from kgn_bench.shapes import PRIMITIVES
from kgn_bench.shapes.base import GraspDensity, Shape
from kgn_bench.shapes.grasp_sampling import antipodal_accepts
from kgn_bench.shapes.mesh_object import MeshObject
from kgn_bench.sim.grasp_verify import verify_grasps

__all__ = ["Agreement", "agreement", "check_labeller", "depth_free_matches", "format_table", "random_grasps",
           "to_json"]

CHECK_DENSITY = GraspDensity(translations=4, angles=8)
"""The family grasps run through physics (recall's denominator)."""
DENSE_DENSITY = GraspDensity(translations=20, angles=72)
"""The family grasps a labelled grasp is compared with (precision)."""


def depth_free_matches(a: np.ndarray, b: np.ndarray, translation: float, rotation: float) -> np.ndarray:
    """(N,) bool: grasp ``a[n]`` (N, 4, 4) agrees with at least one of ``b`` (M, 4, 4), same frame (module
    doc: translation off ``b``'s approach axis under ``translation`` m, symmetric rotation under ``rotation``
    rad)."""
    out = np.zeros(len(a), dtype=bool)
    if len(a) == 0 or len(b) == 0:
        return out
    x_b = b[:, :3, 0]
    for i, T in enumerate(a):
        dt = T[:3, 3][None] - b[:, :3, 3]
        perp = dt - np.einsum("mj,mj->m", dt, x_b)[:, None] * x_b
        near = np.linalg.norm(perp, axis=1) < translation
        if near.any():
            out[i] = bool(np.any(grasp_rotation_error(np.broadcast_to(T[:3, :3], (int(near.sum()), 3, 3)),
                                                      b[near, :3, :3]) < rotation))
    return out


@dataclass(frozen=True)
class Agreement:
    """One shape's comparison (module doc); counts, then the two rates in [0, 1]."""

    shape: str
    dims: dict
    family_checked: int
    family_held: int
    family_accepted: int
    family_held_accepted: int
    labelled: int
    labelled_in_family: int
    candidates_checked: int
    candidates_held: int
    control: int = 0
    control_held: int = 0
    control_accepted: int = 0
    control_agree: int = 0

    @property
    def precision(self) -> float:
        return self.labelled_in_family / self.labelled if self.labelled else math.nan

    @property
    def recall(self) -> float:
        return self.family_held_accepted / self.family_held if self.family_held else math.nan

    @property
    def family_failed_accepted(self) -> int:
        return self.family_accepted - self.family_held_accepted

    @property
    def family_hold_rate(self) -> float:
        return self.family_held / self.family_checked if self.family_checked else math.nan


def agreement(shape: Shape, family: np.ndarray, family_held: np.ndarray, family_accepted: np.ndarray,
              dense: np.ndarray, labelled: np.ndarray, candidates: tuple[int, int] = (0, 0),
              translation: float = 0.01, rotation: float = math.radians(20.0)) -> tuple[Agreement, np.ndarray]:
    """The figures of one shape from its checked family grasps ``family`` (K, 4, 4) with ``family_held`` and
    ``family_accepted`` (K,) (physics, the labeller's test), the dense family ``dense``, the labelled grasps
    ``labelled`` and the labeller's ``candidates`` (checked, held); also the (L,) mask of labelled grasps
    outside the family."""
    in_family = depth_free_matches(labelled, dense, translation, rotation)
    result = Agreement(shape.name, shape.dims(), len(family), int(family_held.sum()), int(family_accepted.sum()),
                       int((family_accepted & family_held).sum()), len(labelled), int(in_family.sum()),
                       *candidates)
    return result, ~in_family


def random_grasps(shape: Shape, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``count`` random grasps about ``shape`` (origin uniform in its bounding box, rotation uniform) with the
    labeller's width for their contacts where it has one, else the full opening; also the test's verdicts."""
    from scipy.spatial.transform import Rotation

    from kgn_bench.gripper import GRIPPER

    lo, hi = shape.mesh().bounds
    poses = np.tile(np.eye(4), (count, 1, 1))
    poses[:, :3, :3] = Rotation.random(count, random_state=rng).as_matrix()
    poses[:, :3, 3] = rng.uniform(lo, hi, size=(count, 3))
    accepted, widths = antipodal_accepts(shape.mesh(), poses, np.full(count, GRIPPER.max_width))
    ok = np.isfinite(widths) & (widths > 0.0) & (widths <= GRIPPER.max_width)
    return poses, np.where(ok, widths, GRIPPER.max_width), accepted


def _labelled_grasps(shape: Shape, config: ImportConfig, folder: Path) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The labeller's grasps on ``shape``'s mesh, in the shape's frame (poses, widths), and its candidates'
    (checked, held) counts."""
    mesh = shape.mesh()
    mesh.export(folder / f"{shape.name}.stl")
    imported = MeshObject(import_mesh(folder / f"{shape.name}.stl", f"check_{shape.name}", config, root=folder,
                                      preview=False))
    offset = make_pose(t=mesh.center_mass)  # the importer's object frame sits at the centre of mass
    poses = np.einsum("ij,njk->nik", offset, imported.verified_grasps.poses)
    counts = imported.manifest["grasps"]
    return poses, imported.verified_grasps.widths, (int(counts["checked"]), int(counts["held"]))


def check_labeller(shapes: list[str] | None = None, seed: int = 0, verify: int = 400, hulls: int = 8,
                   control: int = 100, out: Path | None = None) -> list[Agreement]:
    """Compare the labeller with the closed-form families on one seeded instance of each primitive in
    ``shapes`` (default all); with ``out``, also draw each shape's labelled grasps outside the family (red)
    beside the ones inside it (green) as ``out/<shape>.png``."""
    results = []
    names = list(PRIMITIVES) if shapes is None else shapes
    for k, name in enumerate(names):
        if name not in PRIMITIVES:
            raise InputError(f"unknown primitive {name!r}; known: {', '.join(PRIMITIVES)}")
        shape = PRIMITIVES[name].sample(np.random.default_rng([seed, k]))
        family = shape.grasps(CHECK_DENSITY)
        held = verify_grasps(shape, family.poses, family.widths)
        accepted, _ = antipodal_accepts(shape.mesh(), family.poses, family.widths)
        dense = shape.grasps(DENSE_DENSITY).poses
        with tempfile.TemporaryDirectory(prefix="kgn-labeller-") as tmp:
            poses, widths, counts = _labelled_grasps(shape, ImportConfig(seed=seed, verify=verify, hulls=hulls),
                                                     Path(tmp))
        result, outside = agreement(shape, family.poses, held, accepted, dense, poses, counts)
        if control:
            c_poses, c_widths, c_accepted = random_grasps(shape, control, np.random.default_rng([seed, k, 1]))
            c_held = verify_grasps(shape, c_poses, c_widths)
            result = replace(result, control=control, control_held=int(c_held.sum()),
                             control_accepted=int(c_accepted.sum()), control_agree=int((c_held == c_accepted).sum()))
        results.append(result)
        if out is not None:
            from kgn_bench.viz.objects import draw_grasp_sets

            Path(out).mkdir(parents=True, exist_ok=True)
            draw_grasp_sets(shape.mesh(), [(poses[~outside], widths[~outside], "tab:green", "in the family"),
                                           (poses[outside], widths[outside], "tab:red", "outside the family")],
                            Path(out) / f"{name}.png",
                            title=f"{name}: {len(poses)} labelled grasps, {int(outside.sum())} outside the family")
    return results


def format_table(results: list[Agreement]) -> str:
    """A Markdown table of the figures (module doc), one row per shape."""
    rows = ["| shape | family grasps held in physics | labeller's test accepts (held / failed) | recall | "
            "labeller candidates held | labelled grasps | in a family (precision) | outside a family (held) | "
            "control: held / accepted / verdicts agree |",
            "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        rows.append(f"| {r.shape} | {r.family_held}/{r.family_checked} | {r.family_held_accepted} / "
                    f"{r.family_failed_accepted} | {100 * r.recall:.1f} % | {r.candidates_held}/{r.candidates_checked}"
                    f" | {r.labelled} | {r.labelled_in_family} ({100 * r.precision:.1f} %) | "
                    f"{r.labelled - r.labelled_in_family} | {r.control_held} / {r.control_accepted} / "
                    f"{r.control_agree} of {r.control} |")
    return "\n".join(rows) + "\n"


def to_json(results: list[Agreement]) -> list[dict]:
    """The results as JSON-ready dicts, the two rates included."""
    return [{**asdict(r), "precision": r.precision, "recall": r.recall,
             "family_failed_accepted": r.family_failed_accepted} for r in results]
