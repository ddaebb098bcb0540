"""The four detector variants as configuration, not code forks.

A variant fixes three choices:

* ``scale_branch``: whether the network has the per-bin scale head ŝ (the Euclidean distance
  ‖t_cam‖ from the camera centre to the grasp origin, metres).
* ``box``: the keypoint box whose projection is the keypoint target. ``fixed`` uses side
  a = ``BOX_SIDE`` (0.1 m); ``scale_normalized`` (the paper's sKpt) uses a = k · s · ``BOX_SIDE`` with
  s = ‖t_cam‖ in metres, so the box's image size no longer shrinks with distance.
* ``translation``: how the decoder sets the translation of the PnP pose. ``pnp`` keeps the metric
  PnP translation of the fixed box; ``scale`` keeps the PnP direction and sets ‖t‖ = ŝ; ``depth``
  keeps the direction and sets ‖t‖ from the observed depth at the predicted centre.

| variant         | scale head | box              | translation |
| --------------- | ---------- | ---------------- | ----------- |
| kgn             | no         | fixed            | pnp         |
| kgn_depth       | no         | fixed            | depth       |
| kgnv2_sbranch   | yes        | fixed            | scale       |
| kgnv2           | yes        | scale_normalized | scale       |

``kgn_depth`` uses the weights of ``kgn`` (it differs only at decoding): ``training_variant`` names it.
``MODELS`` names detectors that are other trained models of a variant (``kgnv2_mesh``: ``kgnv2`` trained on
meshes too).

A fourth choice belongs to a trained model, not to the variant's name: ``scale_anchor``, how the scale head
is parameterised (``kgn_bench.model.depth_anchor``). ``none`` (the paper) regresses ŝ = ‖t_cam‖ directly;
``depth`` regresses the residual r = ‖t_cam‖ − d_obs to the distance the depth image observes along the ray
of the grasp centre, and decodes ŝ = d_obs + r̂. A checkpoint records it (``model.checkpoint``), and
``with_scale_anchor`` gives the variant a checkpoint decodes as.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from kgn_bench.errors import InputError

__all__ = ["BOX_SIDE", "MODELS", "VARIANTS", "Variant", "get_variant"]

BOX_SIDE = 0.1
"""w_ref: side of the fixed keypoint box in metres (KGN's canonical 0.1 m)."""


@dataclass(frozen=True)
class Variant:
    """One detector variant; see the module docstring for the meaning of each field."""

    name: str
    scale_branch: bool
    box: Literal["fixed", "scale_normalized"]
    translation: Literal["pnp", "scale", "depth"]
    box_coeff: float = 1.0
    """k of the scale-normalised box a = k · s · BOX_SIDE (unused for ``fixed``)."""
    training_variant: str | None = None
    """The variant whose weights this one loads (None: its own)."""
    scale_anchor: Literal["none", "depth"] = "none"
    """Parameterisation of the scale head: ŝ itself (``none``) or its residual to the observed depth (``depth``)."""

    def __post_init__(self) -> None:
        if self.box not in ("fixed", "scale_normalized"):
            raise ValueError(f"variant {self.name}: unknown box {self.box!r}")
        if self.translation not in ("pnp", "scale", "depth"):
            raise ValueError(f"variant {self.name}: unknown translation {self.translation!r}")
        if self.translation == "scale" and not self.scale_branch:
            raise ValueError(f"variant {self.name}: translation 'scale' needs the scale branch")
        if self.box == "scale_normalized" and self.translation == "pnp":
            raise ValueError(f"variant {self.name}: a scale-normalised box has no metric PnP translation")
        if not self.box_coeff > 0.0:
            raise ValueError(f"variant {self.name}: box_coeff must be positive")
        if self.scale_anchor not in ("none", "depth"):
            raise ValueError(f"variant {self.name}: unknown scale_anchor {self.scale_anchor!r} (none or depth)")
        if self.scale_anchor != "none" and not self.scale_branch:
            raise ValueError(f"variant {self.name}: scale_anchor {self.scale_anchor!r} needs the scale branch")

    @property
    def weights_variant(self) -> str:
        return self.training_variant or self.name

    @property
    def needs_depth(self) -> bool:
        """Whether decoding reads the observed depth image (depth translation or a depth-anchored scale)."""
        return self.translation == "depth" or self.scale_anchor == "depth"

    def with_scale_anchor(self, anchor: str) -> Variant:
        """This variant with the scale head parameterised by ``anchor``; variants without the scale branch are
        returned unchanged (they have no scale head to anchor)."""
        return replace(self, scale_anchor=anchor) if self.scale_branch else self

    def box_sides(self, distances: np.ndarray) -> np.ndarray:
        """Keypoint-box side a (metres) for grasps at camera distances s = ‖t_cam‖ (metres), shape (N,)."""
        s = np.asarray(distances, dtype=float)
        if self.box == "fixed":
            return np.full(s.shape, BOX_SIDE)
        return self.box_coeff * s * BOX_SIDE


VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("kgn", scale_branch=False, box="fixed", translation="pnp"),
        Variant("kgn_depth", scale_branch=False, box="fixed", translation="depth", training_variant="kgn"),
        Variant("kgnv2_sbranch", scale_branch=True, box="fixed", translation="scale"),
        Variant("kgnv2", scale_branch=True, box="scale_normalized", translation="scale"),
    )
}


MODELS: dict[str, str] = {"kgnv2_mesh": "kgnv2"}
"""Detectors that are another trained model of a variant (detector name → variant): decoded as the variant,
with the weights ``<name>.pt`` (``detectors.kgn.weights_path``). ``kgnv2_mesh`` is KGNv2 trained on scenes
that mix the primitives with meshes of pybullet's train split, in random textures, through the benchmark
camera's depth noise (``tasks/train_kgnv2_mesh.toml``); ``kgnv2`` stays the paper's model, trained on the
primitives only."""


def get_variant(name: str) -> Variant:
    """The variant called ``name``; ``ValueError`` listing the known ones otherwise."""
    try:
        return VARIANTS[name]
    except KeyError:
        raise InputError(f"unknown variant {name!r} (known: {', '.join(VARIANTS)})") from None
