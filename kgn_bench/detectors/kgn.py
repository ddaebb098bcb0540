"""The learned detectors ``kgnv2``, ``kgnv2_sbranch``, ``kgn``, ``kgn_depth``, ``kgnv2_mesh``: network, maps, decode.

``detect``: validate the observation, ``model.preprocess.prepare`` (full frame resized by the model's
``input_scale``, standardised, padded), one forward pass, sigmoid on the heatmap logits, then
``model.decode.decode`` (top-k peaks, orientation filter, IPPE PnP, translation per variant) with the
observed depth for ``kgn_depth`` and for depth-anchored scale heads. Candidates are in the camera frame.

Weights: a name looks up ``assets/weights/<name>.pt`` (``kgn_depth`` uses ``kgn``'s, ``kgnv2_sbranch`` the
single-split ``kgnv2_sbranch_single``, ``SHIPPED_AS``); a path loads that file. A detector of
``model.variants.MODELS`` is another trained model of a variant, decoded as that variant, with its own
weights and name.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import torch

from kgn_bench.model.checkpoint import LoadedModel, load_model
from kgn_bench.model.decode import DecodeConfig, decode
from kgn_bench.model.preprocess import prepare
from kgn_bench.model.variants import MODELS, get_variant
from kgn_bench.resources import weights_dir

from .base import Candidates, DetectorError, Observation

__all__ = ["WEIGHTS_DIR", "KGNDetector", "weights_path"]

WEIGHTS_DIR = weights_dir()
"""The shipped weights (``kgn_bench.resources.weights_dir``)."""


SHIPPED_AS = {"kgnv2_sbranch": "kgnv2_sbranch_single"}
"""Variants whose one shipped model has another name: the scale-branch KGNv2 of the paper's ablation is
trained on the single-object split only."""


def weights_path(variant_name: str | None, weights: str | Path | None = None) -> Path:
    """The weights file for ``variant_name`` (a variant or a name of ``MODELS``): ``weights`` if it is a
    path to a file, else the shipped ``<weights>.pt``, else the model's own shipped weights, else those of
    the variant's training variant (``kgnv2`` when neither is given)."""
    if weights is not None and (Path(weights).suffix == ".pt" or Path(weights).is_file()):
        return Path(weights)
    if weights is not None:
        return WEIGHTS_DIR / f"{weights}.pt"
    if variant_name in MODELS:
        return WEIGHTS_DIR / f"{variant_name}.pt"
    name = get_variant(variant_name or "kgnv2").weights_variant
    return WEIGHTS_DIR / f"{SHIPPED_AS.get(name, name)}.pt"


class KGNDetector:
    """A KGN-family detector. ``timing`` holds the last call's seconds per stage: ``preprocess``,
    ``network``, ``decode`` (peaks, filters, translation) and ``pnp``."""

    privileged = False

    def __init__(self, variant: str | None = "kgnv2", weights: str | Path | None = None,
                 model: LoadedModel | None = None, decode_config: DecodeConfig | None = None,
                 threads: int | None = None) -> None:
        """``variant`` None decodes as the variant the weights were trained as; an explicit one (or a name of
        ``MODELS``) must be servable by them (``kgn_depth`` decodes ``kgn`` weights), else
        ``CheckpointError``."""
        wanted = get_variant(MODELS.get(variant, variant)) if variant is not None else None
        if model is None:
            model = load_model(weights_path(variant, weights), wanted)
        self.model = model
        self.variant = wanted.with_scale_anchor(model.variant.scale_anchor) if wanted else model.variant
        self.name = variant if variant in MODELS else self.variant.name
        if self.model.variant.weights_variant != self.variant.weights_variant:
            raise DetectorError(f"model of variant {self.model.variant.name!r} cannot decode as {self.name!r}")
        self.decode_config = decode_config or DecodeConfig()
        self.threads = threads
        self.timing: dict[str, float] = {}

    def reset(self, seed: list[int]) -> None:
        pass

    def maps(self, observation: Observation) -> tuple[dict[str, np.ndarray], np.ndarray]:
        """The prediction maps (numpy, ``hm`` as probabilities) and the image → output affine ``M``."""
        observation.validate()
        t = time.perf_counter()
        self.timing = {}
        try:
            x, M, (ho, wo) = prepare(observation.rgb, observation.depth, self.model.input_config,
                                     self.model.network.output_stride)
        except ValueError as e:
            raise DetectorError(str(e)) from None
        self.timing["preprocess"] = time.perf_counter() - t
        if self.threads:
            torch.set_num_threads(self.threads)
        t = time.perf_counter()
        net = self.model.net
        device = next(net.parameters()).device  # the network may sit on a GPU (training's held-out check)
        with torch.inference_mode():
            out = net(x[None].to(device))
        maps = {k: v[0, :, :ho, :wo].float().cpu().numpy() for k, v in out.items()}
        maps["hm"] = 1.0 / (1.0 + np.exp(-maps["hm"]))
        self.timing["network"] = time.perf_counter() - t
        return maps, M

    def detect(self, observation: Observation) -> Candidates:
        maps, M = self.maps(observation)
        t = time.perf_counter()
        cands = decode(maps, observation.intrinsics.K, M, self.variant, self.decode_config,
                       depth=observation.depth if self.variant.needs_depth else None, timing=self.timing)
        self.timing["decode"] = time.perf_counter() - t - self.timing.get("pnp", 0.0)
        return cands
