"""RGB images: the colour palette shared by drawings and figures, and PNG output."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
from matplotlib import colormaps

from kgn_bench.io import atomic_write

__all__ = ["PALETTE_RGB", "save_png"]

PALETTE_RGB: tuple[tuple[int, int, int], ...] = tuple(
    tuple(round(255 * c) for c in colormaps["tab10"](i)[:3]) for i in range(10)
)
"""matplotlib's tab10 colours as 8-bit RGB, so drawings use the figures' colours."""


def save_png(path: str | os.PathLike[str], image: np.ndarray) -> None:
    """Write an RGB uint8 (H, W, 3) image to ``path`` as PNG, atomically (missing folders are created).
    ``ValueError`` for anything else."""
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ValueError(f"image must be (H, W, 3) uint8, got {image.shape} {image.dtype}")
    ok, buf = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    if not ok:
        raise ValueError(f"OpenCV could not encode a PNG for {path}")
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda f: f.write(buf.tobytes()))
