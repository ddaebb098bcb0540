"""Grasp detectors behind one protocol (``base.Detector``) and a registry by name.

A detector is named either by its registered name (``DETECTORS``) or, for one's own detector outside this
package, by ``module:attribute`` (e.g. ``my_lab.grasping:MyDetector``): a class or function in an importable
module that returns an object following ``base.Detector`` when called without arguments.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from pathlib import Path

from kgn_bench.errors import InputError
from kgn_bench.model.variants import MODELS

from .antipodal import AntipodalDetector
from .base import Candidates, Detector, DetectorError, Observation
from .oracle import OracleDetector
from .random import RandomDetector

__all__ = ["DETECTORS", "LEARNED", "WEIGHTED", "Candidates", "Detector", "DetectorError", "Observation",
           "detector_factory", "make_detector", "shipped_weights"]


def _learned(variant: str) -> Callable[..., Detector]:
    def make(weights=None) -> Detector:
        from .kgn import KGNDetector  # torch is imported only when a learned detector is used

        return KGNDetector(variant, weights)

    return make


def _vgn(weights=None) -> Detector:
    """VGN (Breyer et al., CoRL 2020) as GIGA re-trained it for one side view: a 3D CNN on a 40³ TSDF of the
    workspace cube, VGN's voxel selection with GIGA's settings (``detectors.vgn``)."""
    from .vgn import VGNDetector  # torch is imported only when the detector is used

    return VGNDetector(weights)


LEARNED = ("kgnv2", "kgnv2_sbranch", "kgn", "kgn_depth", *MODELS)
"""The KGN-family detectors backed by trained weights (one per model variant, and the other trained models of
``model.variants.MODELS``; ``detectors.kgn``)."""

WEIGHTED = (*LEARNED, "vgn")
"""Every registered detector that loads trained weights (``make_detector`` passes ``weights`` on to them)."""



def shipped_weights(name: str) -> Path | None:
    """The weights file a registered detector loads when given none (``assets/weights/…``; it may not exist
    yet); None for a detector without weights. Its SHA-256 is part of a run's identity and its model card
    (the ``.md`` beside it) goes into results bundles."""
    if name in LEARNED:
        from .kgn import weights_path

        return weights_path(name)
    if name == "vgn":
        from .vgn import vgn_weights_path

        return vgn_weights_path()
    return None


DETECTORS: dict[str, Callable[..., Detector]] = {
    "antipodal": AntipodalDetector,
    "oracle": OracleDetector,
    "random": RandomDetector,
    **{v: _learned(v) for v in LEARNED},
    "vgn": _vgn,
}


def detector_factory(name: str) -> Callable[..., Detector]:
    """The factory of ``name``: a registered detector, or ``module:attribute`` imported from the Python path;
    ``ValueError`` naming the problem (unknown name, module that fails to import, missing attribute).

    A plain ``ValueError``, not a ``KGNBenchError``: every caller re-words it with its context into its own
    user error (``bench.runner.build_detector``: ``RunError``; ``bench.benchmark.load_plan``: ``ConfigError``
    naming the plan file), and the runner lets a ``KGNBenchError`` through unchanged."""
    if name in DETECTORS:
        return DETECTORS[name]
    module, sep, attribute = name.partition(":")
    if not sep:
        raise InputError(f"unknown detector {name!r}; known: {', '.join(sorted(DETECTORS))} "
                         "(or module:attribute for your own)")
    try:
        factory = getattr(importlib.import_module(module), attribute)
    except ImportError as e:
        raise InputError(f"detector {name!r}: cannot import {module!r} ({e})") from None
    except AttributeError:
        raise InputError(f"detector {name!r}: module {module!r} has no {attribute!r}") from None
    if not callable(factory):
        raise InputError(f"detector {name!r}: {attribute!r} is not a class or function")
    return factory


def make_detector(name: str, weights=None) -> Detector:
    """The detector ``name`` (see the module docstring); learned ones take ``weights`` (a name under
    assets/weights or a path; default the shipped weights). Raises ``ValueError`` with the reason."""
    factory = detector_factory(name)
    if name in WEIGHTED:
        return factory(weights)
    if weights is not None:
        raise InputError(f"detector {name!r} takes no weights")
    detector = factory()
    missing = [a for a in ("name", "privileged", "reset", "detect") if not hasattr(detector, a)]
    if missing:
        raise InputError(f"detector {name!r} lacks {', '.join(missing)} (see kgn_bench.detectors.base.Detector)")
    return detector
