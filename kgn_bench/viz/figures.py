"""Figures with matplotlib (the Agg renderer; no display, no global pyplot state): the benchmark's bar
chart with interval whiskers, line panels (the PnP-noise study) and training curves, saved atomically.

Figures are built with ``matplotlib.figure.Figure`` directly, sized for a paper column or page at 150 dpi,
and take any Unicode in their labels (DejaVu Sans, matplotlib's own font).
"""

from __future__ import annotations

import io
import os
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from kgn_bench.io import atomic_write

__all__ = ["DPI", "Line", "Panel", "bar_chart", "line_panels", "save_figure", "save_training_curves", "training_figure",
           "vgn_training_figure"]

DPI = 150
"""Resolution of saved figures."""


@dataclass(frozen=True)
class Line:
    """One series of a line panel; ``color`` indexes matplotlib's tab10 cycle."""

    label: str
    x: Sequence[float]
    y: Sequence[float]
    color: int = 0
    dashed: bool = False
    markers: bool = True
    band: tuple[Sequence[float], Sequence[float]] | None = None
    """Optional (low, high) per point, drawn as a shaded band (an interval)."""


@dataclass(frozen=True)
class Panel:
    """One axes of ``line_panels``."""

    title: str
    xlabel: str
    ylabel: str
    lines: Sequence[Line] = field(default_factory=tuple)
    log_y: bool = False


def _tab10(i: int) -> str:
    return f"C{i % 10}"


def save_figure(fig: Figure, path: str | os.PathLike[str]) -> None:
    """Render ``fig`` to PNG and write it atomically to ``path`` (``kgn_bench.io.atomic_write``)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    atomic_write(path, lambda f: f.write(buf.getvalue()))


def bar_chart(groups: Sequence[str], series: Sequence[str], values: np.ndarray, lows: np.ndarray,
              highs: np.ndarray, *, title: str, ylabel: str, ylim: tuple[float, float] = (0.0, 108.0),
              per_row: int = 8) -> Figure:
    """Grouped bars: ``values`` (G, S) for G groups on the x axis and S series (one colour each), with
    whiskers from ``lows`` to ``highs`` (e.g. Wilson 95 % intervals) and the value printed above each bar.
    NaN values leave a gap (a detector that has no run for that column). Group labels wrap at 18 characters.

    More than ``per_row`` groups are spread over ceil(G / per_row) rows of equal length, one axes each; a row
    gives bar slots only to the series with a value in it (a detector that runs a few tasks only does not
    leave a gap in every group), and one legend above the figure, under the title, names every series in its
    colour."""
    values, lows, highs = (np.asarray(a, dtype=float) for a in (values, lows, highs))
    if values.shape != (len(groups), len(series)) or lows.shape != values.shape or highs.shape != values.shape:
        raise ValueError(f"values, lows and highs must be ({len(groups)}, {len(series)})")
    n_rows = max(1, -(-len(groups) // per_row))
    row_len = -(-len(groups) // n_rows) if groups else 0
    fig = Figure(figsize=(max(6.5, 1.25 * row_len + 2.0), 0.6 + 3.0 * n_rows), layout="constrained")
    axes = fig.subplots(n_rows, 1, squeeze=False)[:, 0]
    for r, ax in enumerate(axes):
        in_row = np.arange(r * row_len, min(len(groups), (r + 1) * row_len))
        present = [j for j in range(len(series)) if np.isfinite(values[in_row, j]).any()]
        width = 0.8 / max(1, len(present))
        x = np.arange(len(in_row))
        for k, j in enumerate(present):
            ok = np.isfinite(values[in_row, j])
            xs = x[ok] + (k - (len(present) - 1) / 2) * width
            v, lo, hi = values[in_row[ok], j], lows[in_row[ok], j], highs[in_row[ok], j]
            ax.bar(xs, v, width * 0.92, color=_tab10(j), yerr=np.vstack([v - lo, hi - v]), capsize=2,
                   error_kw={"elinewidth": 0.8, "ecolor": "0.2"})
            for xi, vi, h in zip(xs, v, hi):  # the value above its whisker
                ax.text(xi, h + 0.01 * (ylim[1] - ylim[0]), f"{vi:.0f}", ha="center", va="bottom", fontsize=5.5)
        ax.set_xticks(x, [textwrap.fill(groups[g], 18) for g in in_row], fontsize=8)
        ax.set_xlim(-0.5, row_len - 0.5)
        ax.set_ylabel(ylabel)
        ax.set_ylim(*ylim)
        ax.grid(axis="y", color="0.9")
        ax.set_axisbelow(True)
    fig.legend(handles=[Patch(color=_tab10(j), label=name) for j, name in enumerate(series)], fontsize=7,
               ncols=min(len(series), 7), loc="outside upper center", frameon=False, title=title,
               title_fontsize=10)
    return fig


def line_panels(panels: Sequence[Panel], *, suptitle: str | None = None) -> Figure:
    """Side-by-side axes, one per ``Panel``, each with its own legend."""
    fig = Figure(figsize=(4.2 * len(panels), 3.4), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    for ax, panel in zip(axes, panels):
        for line in panel.lines:
            ax.plot(line.x, line.y, color=_tab10(line.color), linestyle="--" if line.dashed else "-",
                    marker="o" if line.markers else None, markersize=2.5, linewidth=1.2, label=line.label)
            if line.band is not None:
                ax.fill_between(line.x, line.band[0], line.band[1], color=_tab10(line.color), alpha=0.15,
                                linewidth=0)
        if panel.log_y:
            ax.set_yscale("log")
        ax.set_title(panel.title, fontsize=9)
        ax.set_xlabel(panel.xlabel)
        ax.set_ylabel(panel.ylabel)
        ax.grid(color="0.9", which="both")
        if panel.lines:
            ax.legend(fontsize=6)
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    return fig


def training_figure(history: Sequence[dict[str, Any]], title: str) -> Figure:
    """Training curves from a run's ``history``: the mean losses per epoch (log scale) on the left, the
    held-out GSR / GCR / OSR at each evaluated epoch and threshold on the right."""
    fig = Figure(figsize=(9.0, 3.4), layout="constrained")
    left, right = fig.subplots(1, 2)
    epochs = [h["epoch"] for h in history]
    for i, key in enumerate(("total", "hm", "reg", "kpts", "width", "scale")):
        ys = [h.get(key) for h in history]
        if any(y is not None for y in ys):
            left.plot(epochs, [np.nan if y is None else y for y in ys], color=_tab10(i), label=key, linewidth=1.2)
    left.set_yscale("log")
    left.set(xlabel="epoch", ylabel="mean loss", title="training loss")
    left.grid(color="0.9", which="both")
    left.legend(fontsize=6, ncols=2)
    evals = [h for h in history if isinstance(h.get("eval"), dict)]
    styles = {"gsr": "-", "gcr": "--", "osr": ":"}
    for t, label in enumerate(evals[0]["eval"] if evals else ()):
        for metric, style in styles.items():
            ys = [h["eval"].get(label, {}).get(metric) for h in evals]
            right.plot([h["epoch"] for h in evals], [np.nan if y is None else 100 * y for y in ys],
                       color=_tab10(t), linestyle=style, marker="o", markersize=2.5, label=f"{metric.upper()} {label}")
    views = evals[-1].get("eval_views", "?") if evals else "?"
    right.set(xlabel="epoch", ylabel="%", ylim=(0, 100), title=f"held-out ({views} test views)")
    right.grid(color="0.9")
    if evals:
        right.legend(fontsize=5, ncols=3)
    fig.suptitle(title, fontsize=10)
    return fig


def vgn_training_figure(history: Sequence[dict[str, Any]], title: str) -> Figure:
    """VGN's training curves from a run's ``history`` (``training.vgn_train``): the mean losses per labelled
    voxel and epoch (log scale; the held-out loss dashed) on the left, the held-out accuracy, precision and
    recall of ``quality ≥ 0.5`` and, where the data stores every yaw, the rotation hit rate on the right."""
    fig = Figure(figsize=(9.0, 3.4), layout="constrained")
    left, right = fig.subplots(1, 2)
    epochs = [h["epoch"] for h in history]

    def series(key: str) -> list[float]:
        return [np.nan if h.get(key) is None else float(h[key]) for h in history]

    for i, key in enumerate(("loss", "bce", "rotation", "width")):
        if any(h.get(key) is not None for h in history):
            left.plot(epochs, series(key), color=_tab10(i), label=key, linewidth=1.2)
    if any(h.get("held_out_loss") is not None for h in history):
        left.plot(epochs, series("held_out_loss"), color=_tab10(0), linestyle="--", label="held-out loss",
                  linewidth=1.2)
    left.set_yscale("log")
    left.set(xlabel="epoch", ylabel="mean loss per label", title="training loss")
    left.grid(color="0.9", which="both")
    left.legend(fontsize=6, ncols=2)
    for i, key in enumerate(("accuracy", "precision", "recall", "rotation_hit")):
        if any(h.get(key) is not None for h in history):
            right.plot(epochs, [100 * y for y in series(key)], color=_tab10(i), marker="o", markersize=2.5,
                       linewidth=1.2, label=key.replace("_", " "))
    right.set(xlabel="epoch", ylabel="%", ylim=(0, 100), title="held-out scenes")
    right.grid(color="0.9")
    if right.lines:
        right.legend(fontsize=6)
    fig.suptitle(title, fontsize=10)
    return fig


def save_training_curves(weights: str | os.PathLike[str]) -> Path | None:
    """Draw the training curves of shipped weights ``<dir>/<name>.pt`` (``model.checkpoint.export_weights`` or
    ``model.vgn_checkpoint.export_vgn_weights``) to ``<dir>/<name>_training.png``, the image their model card
    links: ``training_figure`` for KGN's, titled ``<name>: <training config>``, ``vgn_training_figure`` for
    VGN's, titled ``<name>: <scenes> scenes``; returns its path, or None (nothing written) when the weights
    carry no history."""
    from kgn_bench.model.checkpoint import checkpoint_format, load_checkpoint
    from kgn_bench.model.vgn_checkpoint import VGN_FORMAT, load_vgn_checkpoint

    weights = Path(weights)
    kind = checkpoint_format(weights)  # None: load_checkpoint names the problem
    name = weights.stem
    png = weights.parent / f"{name}_training.png"
    if kind == VGN_FORMAT:
        data = load_vgn_checkpoint(weights)
        if not data.get("history"):
            return None
        scenes = data.get("dataset", {}).get("scenes", "?")
        save_figure(vgn_training_figure(data["history"], f"{name}: {scenes} scenes"), png)
        return png
    data = load_checkpoint(weights)
    if not data.get("history"):
        return None
    save_figure(training_figure(data["history"], f"{name}: {data.get('train', {}).get('name', '')}"), png)
    return png
