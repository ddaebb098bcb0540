"""The straight-line grasp execution's distances (metres, along the grasp's approach axis +x).

The executor (``sim.control``, with ``config.ExecutionConfig``) moves the TCP to the pre-grasp
``T_world_grasp · (−PREGRASP_DISTANCE, 0, 0)``, then straight in to ``GRASP_DEPTH`` past the grasp origin,
``T_world_grasp · (GRASP_DEPTH, 0, 0)``. Those defaults live here, below every layer, so that the grasp
families' self-collision filter (``shapes.household``), the grasp check in physics (``sim.grasp_verify``) and
the task config read the same numbers; a task may still override its own (``[execution]``).
"""

from __future__ import annotations

__all__ = ["GRASP_DEPTH", "PREGRASP_DISTANCE"]

PREGRASP_DISTANCE = 0.10
"""How far back along the approach axis (m) the straight approach starts (``ExecutionConfig.pregrasp_distance``)."""

GRASP_DEPTH = 0.01
"""How much further than the grasp origin (m) the TCP goes along the approach (``ExecutionConfig.grasp_depth``)."""
