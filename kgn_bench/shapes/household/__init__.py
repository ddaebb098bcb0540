"""Household objects for the closed-loop benchmark: not in the training data, built from pieces.

Each object is a frozen dataclass of sizes in metres, sampled uniformly from ``RANGES``; its object frame is
documented on the class. The pieces are the primitives' own: boxes, cylinders, spheres, the hollow rings of
boxes of the tube (``_annulus_boxes``) and the bowl's shell of boxes (``SemiSphere``), and small convex meshes
(tapered capsules: the convex hull of two spheres; a frustum). Hollow parts are hollow in the collision
geometry. The visual mesh is the concatenation of watertight part meshes (overlapping where parts join), smooth
solids of revolution where a part is one.

Grasp families (only the oracle uses them) are the families of the parts, in the object frame:

* **tube pinch** (``families.tube_family``): across a round part at a point ``c`` of its centre line with
  unit tangent ``t``: for each angle β, outward normal ``n = cos β·u + sin β·(t × u)`` (``u`` a reference
  normal), approach ``−n`` (towards the centre line), closing axis ``t × approach``, origin at ``c``;
  ``_side_family`` of the PS shapes is this family for a vertical axis;
* **box pinch** (``families.box_family``): the cuboid's family on a box part: approach along ±each axis
  whose extent is at least ``MIN_APPROACH_EXTENT`` (the fingers need something to close on), closing along
  one of the two others, the origin ``min(2 cm, d/2)`` inside the entry face, at N positions along the remaining axis;
* **rim pinch**: the tube's rim family (``_revolved_family`` of the top or bottom orientation) on a thin wall.

Width = the part's extent across the closing axis + ``PINCH_CLEARANCE`` (1.5 cm), so every width fits the
gripper. The labelling proxy ignores the grasped object itself, so grasps whose gripper would run into
another part of the same object are dropped here (``families.gripper_sweep_free``): the fingers (from the
opening the executor uses, ``GRIPPER.opening``: width + 1 cm, in to 3 mm outside the pinched extent, and
reaching ``execution.GRASP_DEPTH`` (1 cm) past the grasp origin as the executor pushes on) and the palm and
wrist, swept back along the approach over the pre-grasp distance (``execution.PREGRASP_DISTANCE``, 10 cm),
must contain no sample point of the object's surface.

Rest poses are chosen to exercise every natural resting state of each object (these are not the quasi-static
estimates of the PS shapes: the objects are not training data); gravity then settles them.

Modules: ``parts`` (the part builders), ``families`` (the grasp families and the self-collision filter),
``base`` (``HouseholdShape``), ``vessels`` (mug, bottle, footed bowl, can) and ``tools`` (hammer, banana,
C-clamp, L-bracket); this package names them all and keeps their registry order.
"""

from __future__ import annotations

from kgn_bench.shapes.household.base import HouseholdShape
from kgn_bench.shapes.household.families import MIN_APPROACH_EXTENT, PINCH_CLEARANCE, gripper_sweep_free
from kgn_bench.shapes.household.tools import Banana, CClamp, Hammer, LBracket
from kgn_bench.shapes.household.vessels import Bottle, Can, FootedBowl, Mug

__all__ = [
    "HOUSEHOLD_CLASSES",
    "MIN_APPROACH_EXTENT",
    "PINCH_CLEARANCE",
    "Banana",
    "Bottle",
    "CClamp",
    "Can",
    "FootedBowl",
    "Hammer",
    "HouseholdShape",
    "LBracket",
    "Mug",
    "gripper_sweep_free",
]

HOUSEHOLD_CLASSES: tuple[type[HouseholdShape], ...] = (Mug, Bottle, FootedBowl, Hammer, Banana, CClamp, Can, LBracket)
"""The household objects in registry order (``shapes.HOUSEHOLD``)."""
