"""PNG figures drawn with OpenCV and numpy only (no matplotlib): line charts, grouped bar charts with
whiskers, panel stacking, "nice" tick values and an atomic PNG writer.

Image conventions: every figure is an RGB ``uint8`` array of shape (height, width, 3) on a white
background, while sizes are given as ``(width, height)`` in pixels, as in OpenCV. Row 0 is the top of the
image, so larger y values are drawn at smaller rows. Colours are RGB tuples of ints in 0–255. Data values
are in whatever unit the caller plots (the axis labels should say which); only pixels are fixed here.
Text is drawn with ``cv2.FONT_HERSHEY_SIMPLEX``, which has ASCII glyphs only (other characters print as
``?``). Write figures with ``save_png``, which converts RGB to OpenCV's BGR order.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

import cv2
import numpy as np

from kgn_bench.io import atomic_write

__all__ = [
    "LEGEND_LOCATIONS",
    "PALETTE_RGB",
    "Bar",
    "Series",
    "bar_chart",
    "hstack",
    "line_panel",
    "nice_ticks",
    "save_png",
    "vstack",
]

PALETTE_RGB: tuple[tuple[int, int, int], ...] = (
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
    (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207),
)
"""Ten distinct RGB colours in matplotlib's tab10 order (blue, orange, green, red, purple, brown, pink,
grey, olive, cyan), for callers to colour series with."""

LEGEND_LOCATIONS = ("upper left", "upper right", "lower left", "lower right", "best", "outside")
"""Accepted ``legend_loc`` values: a corner inside the plot area, ``"best"`` (the corner that covers the
fewest data pixels, in the order upper left, upper right, lower right, lower left on ties) or ``"outside"``
(rows above the plot area, below the title, never covering data)."""

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_WHITE = (255, 255, 255)
_INK = (30, 30, 30)  # text
_FRAME = (50, 50, 50)  # axes box and tick marks
_GRID = (222, 222, 222)
_MINOR_GRID = (240, 240, 240)
_WHISKER = (35, 35, 35)
_LEGEND_EDGE = (190, 190, 190)
_MIN_SIZE = 64  # px, smallest accepted width or height
_MIN_PLOT = 24  # px, smallest plot area left after the margins


# --------------------------------------------------------------------------------------------- data types


@dataclass(frozen=True)
class Series:
    """One line of a ``line_panel``: points (x[i], y[i]) in data units joined in the given order.

    ``x`` and ``y`` accept any 1-D sequence of numbers and are stored as tuples of floats. x must be finite;
    a NaN in y is a gap (the point is skipped and the line broken there); ±inf is rejected. ``color`` is RGB
    0–255. ``dashed`` draws the line dashed; ``marker`` puts a small filled circle on each point (an
    isolated point between gaps always gets one). A series with an empty ``label`` is left out of the
    legend. Raises ``ValueError`` for an empty series, x/y length mismatch, non-finite x, infinite y or a
    bad colour."""

    label: str
    x: tuple[float, ...]
    y: tuple[float, ...]
    color: tuple[int, int, int]
    dashed: bool = False
    marker: bool = True

    def __post_init__(self) -> None:
        x = _float_tuple(self.x, f"series {self.label!r} x")
        y = _float_tuple(self.y, f"series {self.label!r} y")
        if not x:
            raise ValueError(f"series {self.label!r} is empty")
        if len(x) != len(y):
            raise ValueError(f"series {self.label!r}: {len(x)} x values but {len(y)} y values")
        if not all(math.isfinite(v) for v in x):
            raise ValueError(f"series {self.label!r}: x values must be finite")
        if any(math.isinf(v) for v in y):
            raise ValueError(f"series {self.label!r}: y values must be finite or NaN (a gap), not inf")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "color", _check_color(self.color, f"series {self.label!r} color"))


@dataclass(frozen=True)
class Bar:
    """One bar of a ``bar_chart``, in data units: height ``value`` (drawn from 0), an optional whisker from
    ``low`` to ``high`` (e.g. a Wilson interval; with only one of them the whisker runs to ``value``) and an
    optional ``label`` printed above the bar (below it for negative values). Raises ``ValueError`` for
    non-finite numbers or low > high."""

    value: float
    low: float | None = None
    high: float | None = None
    label: str = ""

    def __post_init__(self) -> None:
        for name in ("value", "low", "high"):
            v = getattr(self, name)
            if v is None and name != "value":
                continue
            v = float(v)
            if not math.isfinite(v):
                raise ValueError(f"bar {name} must be finite, got {v}")
            object.__setattr__(self, name, v)
        if self.low is not None and self.high is not None and self.low > self.high:
            raise ValueError(f"bar whisker low {self.low} > high {self.high}")


# --------------------------------------------------------------------------------------------- ticks


def nice_ticks(lo: float, hi: float, target: int = 6) -> np.ndarray:
    """Evenly spaced tick values with a step of 1, 2 or 5 × 10^k covering [lo, hi] (first tick ≤ lo, last
    ≥ hi, up to float rounding of 1e-9 of a step) and numbering as close to ``target`` as possible (at least
    2). Values are multiples of the step computed as integer × mantissa / 10^k, so 0.1-steps print cleanly.
    ``lo == hi`` is widened by 10 % of ``|lo|`` (or by 1 around 0). Raises ``ValueError`` for non-finite
    bounds, ``lo > hi`` or ``target < 2``."""
    lo, hi = float(lo), float(hi)
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"tick range must be finite, got [{lo}, {hi}]")
    if lo > hi:
        raise ValueError(f"tick range is reversed: lo {lo} > hi {hi}")
    if target < 2:
        raise ValueError(f"target must be at least 2 ticks, got {target}")
    if lo == hi:
        d = abs(lo) * 0.1 if lo != 0 else 1.0
        lo, hi = lo - d, hi + d
    e0 = math.floor(math.log10((hi - lo) / (target - 1)))
    best: tuple[tuple[int, float], int, int, int, int] | None = None
    for e in (e0 - 1, e0, e0 + 1):
        for m in (1, 2, 5):
            step = m * 10.0**e
            tol = 1e-9 * max(1.0, abs(lo / step), abs(hi / step))
            i0 = math.floor(lo / step + tol)
            i1 = max(math.ceil(hi / step - tol), i0 + 1)
            key = (abs(i1 - i0 + 1 - target), -step)
            if best is None or key < best[0]:
                best = (key, m, e, i0, i1)
    assert best is not None
    _, m, e, i0, i1 = best
    idx = np.arange(i0, i1 + 1, dtype=np.float64)
    return idx * (m * 10.0**e) if e >= 0 else idx * m / 10.0 ** (-e)


def _format_tick(value: float, step: float) -> str:
    """Tick label for ``value`` on an axis with tick spacing ``step``: as many decimals as the step needs,
    trailing zeros dropped ("0.5", "1", "1.5", "10"); scientific ("2e6", "2.5e-5") for huge or tiny values."""
    if value == 0 or abs(value) < abs(step) * 1e-6:
        return "0"
    if abs(value) >= 1e6 or abs(step) < 1e-4:
        text = f"{value:.3g}"
        if "e" in text:
            mantissa, exponent = text.split("e")
            text = f"{mantissa}e{int(exponent)}"
        return text
    decimals = max(0, -math.floor(math.log10(abs(step)) + 1e-9))
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def _format_log_tick(value: float) -> str:
    """Label of a log-axis tick ``value`` (> 0): plain for 0.001 … 10000, else "1e-5" style."""
    e = math.floor(math.log10(value) + 1e-9)
    if -3 <= e <= 4:
        return _format_tick(value, 10.0**e)
    mantissa = value / 10.0**e
    return f"1e{e}" if abs(mantissa - 1) < 1e-6 else f"{mantissa:.3g}e{e}"


def _snap_limits(lo: float, hi: float, steps: Sequence[float], pad_lo: float = 0.05,
                 pad_hi: float = 0.05) -> tuple[float, float]:
    """Axis limits around data [lo, hi] (lo < hi): padded by ``pad_lo`` / ``pad_hi`` × span, then each end
    moved outward to a multiple of the first of ``steps`` that is less than one more padding away (otherwise
    the padded value is kept). A zero padding keeps that end at the data (or on a multiple it touches)."""
    span = hi - lo
    a, b = lo - pad_lo * span, hi + pad_hi * span
    for step in steps:
        t = math.floor(a / step + 1e-9) * step
        if a - t < 0.999 * pad_lo * span or a - t <= 1e-12 * span:
            a = t
            break
    for step in steps:
        t = math.ceil(b / step - 1e-9) * step
        if t - b < 0.999 * pad_hi * span or t - b <= 1e-12 * span:
            b = t
            break
    return a, b


def _widen(lo: float, hi: float) -> tuple[float, float]:
    """[lo, hi] with a zero-width range (or one below float resolution, 1e-9 of the values) widened by 10 %
    of the value (by 1 around 0)."""
    if hi - lo > 1e-9 * max(abs(lo), abs(hi)):
        return lo, hi
    d = abs(lo) * 0.1 if lo != 0 else 1.0
    return lo - d, hi + d


def _tick_step(lo: float, hi: float) -> float:
    ticks = nice_ticks(lo, hi)
    return float(ticks[1] - ticks[0])


def _linear_limits(lo: float, hi: float) -> tuple[float, float]:
    """Auto limits on a linear axis for data in [lo, hi]: 5 % padding, snapped to (half) nice ticks."""
    lo, hi = _widen(lo, hi)
    step = _tick_step(lo, hi)
    return _snap_limits(lo, hi, (step, step / 2))


def _pick_linear_ticks(lo: float, hi: float, length_px: float, label_px: Callable[[str], float],
                       gap_px: float, target: int = 6) -> tuple[np.ndarray, list[str]]:
    """Ticks at multiples of a 1/2/5 × 10^k step inside [lo, hi] on an axis ``length_px`` long: the count
    closest to ``target`` among the steps whose labels (extent ``label_px(text)`` along the axis) keep
    ``gap_px`` apart, else the sparsest step with 2 ticks; returns the values and their labels."""
    span = hi - lo
    e0 = math.floor(math.log10(span))
    best: tuple[tuple[bool, int, float], np.ndarray, list[str]] | None = None
    for e in range(e0 - 2, e0 + 2):
        for m in (1, 2, 5):
            step = m * 10.0**e
            tol = 1e-9 * max(1.0, abs(lo / step), abs(hi / step))
            i0, i1 = math.ceil(lo / step - tol), math.floor(hi / step + tol)
            n = i1 - i0 + 1
            if n < 2 or n > 4 * target:
                continue
            idx = np.arange(i0, i1 + 1, dtype=np.float64)
            ticks = idx * step if e >= 0 else idx * m / 10.0 ** (-e)
            labels = [_format_tick(float(v), step) for v in ticks]
            fits = step / span * length_px >= max(label_px(t) for t in labels) + gap_px
            key = (not fits, abs(n - target) if fits else n, -step)
            if best is None or key < best[0]:
                best = (key, ticks, labels)
    if best is None:  # only for ranges near float resolution: label the ends
        return np.array([lo, hi]), [f"{lo:.6g}", f"{hi:.6g}"]
    return best[1], best[2]


def _pick_log_ticks(lo: float, hi: float, length_px: float, label_px: float,
                    measure: Callable[[str], float]) -> tuple[np.ndarray, np.ndarray]:
    """Major and minor tick values (data units) for a log axis spanning 10**lo … 10**hi: decades (every
    n-th one if crowded) and, when few decades are shown, 2…9 × 10^k minor grid values. With no decade
    inside, 1/2/5 × 10^k values (or linear nice ticks) are the major ticks."""
    e_lo, e_hi = math.ceil(lo - 1e-9), math.floor(hi + 1e-9)
    decades = np.arange(e_lo, e_hi + 1)
    px_per_decade = length_px / (hi - lo)
    every = max(1, math.ceil(label_px / px_per_decade))
    major_e = decades[decades % every == 0] if every > 1 else decades
    minor: list[float] = []
    if every == 1 and hi - lo <= 6:
        for e in range(math.floor(lo) - 1, math.ceil(hi) + 1):
            minor.extend(m * 10.0**e for m in range(2, 10))
    minor_arr = np.array([v for v in minor if lo - 1e-9 <= math.log10(v) <= hi + 1e-9])
    if len(major_e) >= 2:
        return 10.0 ** major_e.astype(np.float64), minor_arr
    candidates = [m * 10.0**e for e in range(math.floor(lo) - 1, math.ceil(hi) + 1) for m in (1, 2, 5)]
    inside = np.array([v for v in candidates if lo - 1e-9 <= math.log10(v) <= hi + 1e-9])
    if len(inside) >= 2:
        return inside, np.array([])
    ticks, _ = _pick_linear_ticks(10.0**lo, 10.0**hi, length_px, measure, label_px)
    return ticks[ticks > 0], np.array([])


# --------------------------------------------------------------------------------------------- style, text


@dataclass(frozen=True)
class _Style:
    """Sizes for one figure, scaled with the image: font scales (Hershey units) and pixel lengths."""

    tick: float
    label: float
    title: float
    text: int  # text stroke thickness, px
    title_text: int
    line: int  # data line thickness, px
    marker: int  # marker radius, px
    pad: int  # general spacing, px
    tick_len: int
    dash: tuple[float, float]  # dashed lines: on, off lengths in px

    @staticmethod
    def for_size(width: int, height: int) -> _Style:
        k = min(max(min(width / 640, height / 480), 0.6), 3.0)
        f = max(k, 0.8)  # fonts shrink less than lines: small panels stay readable
        line = max(2, round(2 * k))
        # round caps grow each dash by the line thickness: the off length makes up for it
        return _Style(tick=0.45 * f, label=0.52 * f, title=0.62 * f, text=max(1, round(k)),
                      title_text=max(1, round(1.5 * k)), line=line, marker=max(3, round(3.5 * k)),
                      pad=max(4, round(8 * k)), tick_len=max(3, round(5 * k)),
                      dash=(max(6.0, 8.0 * k), max(4.0, 5.0 * k) + line))


def _text_size(text: str, scale: float, thick: int) -> tuple[int, int, int]:
    """(width, cap height, descent below the baseline) of ``text`` in px."""
    (w, h), base = cv2.getTextSize(text, _FONT, scale, thick)
    return w, h, base


def _put_text(img: np.ndarray, text: str, x: float, y: float, scale: float, thick: int, ha: str = "left",
              va: str = "baseline", color: tuple[int, int, int] = _INK) -> None:
    """Draw ``text`` anchored at pixel (x, y): ``ha`` left/center/right, ``va`` top (cap top), center,
    baseline or bottom (descender bottom)."""
    w, h, base = _text_size(text, scale, thick)
    x -= {"left": 0.0, "center": w / 2, "right": float(w)}[ha]
    y += {"top": float(h), "center": h / 2, "baseline": 0.0, "bottom": -float(base)}[va]
    cv2.putText(img, text, (round(x), round(y)), _FONT, scale, color, thick, cv2.LINE_AA)


def _fit_scale(texts: Sequence[str], scale: float, thick: int, max_width: float, min_scale: float) -> float:
    """Largest font scale ≤ ``scale`` (down to ``min_scale``) at which every text is at most ``max_width``."""
    widest = max((_text_size(t, scale, thick)[0] for t in texts if t), default=0)
    if widest <= max_width or widest == 0:
        return scale
    return max(min_scale, scale * max_width / widest)


def _paste_darker(canvas: np.ndarray, tile: np.ndarray, x: int, y: int) -> None:
    """Composite dark-on-white ``tile`` onto ``canvas`` with its top-left at (x, y) (per-pixel minimum),
    clipped to the canvas."""
    h, w = tile.shape[:2]
    x0, y0 = max(x, 0), max(y, 0)
    x1, y1 = min(x + w, canvas.shape[1]), min(y + h, canvas.shape[0])
    if x1 <= x0 or y1 <= y0:
        return
    region = canvas[y0:y1, x0:x1]
    np.minimum(region, tile[y0 - y : y1 - y, x0 - x : x1 - x], out=region)


def _vertical_text(text: str, scale: float, thick: int) -> np.ndarray:
    """``text`` rendered dark on white and rotated 90° counter-clockwise (reads bottom to top)."""
    w, h, base = _text_size(text, scale, thick)
    tile = np.full((h + base + 2, w + 2, 3), 255, np.uint8)
    cv2.putText(tile, text, (1, h + 1), _FONT, scale, _INK, thick, cv2.LINE_AA)
    return np.ascontiguousarray(np.rot90(tile))


# --------------------------------------------------------------------------------------------- checks


def _float_tuple(values: Sequence[float], what: str) -> tuple[float, ...]:
    arr = np.asarray(values, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"{what} must be a 1-D sequence, got shape {arr.shape}")
    return tuple(float(v) for v in arr)


def _check_color(color: Sequence[int], what: str) -> tuple[int, int, int]:
    values = tuple(color)
    if len(values) != 3 or not all(float(v) == int(v) and 0 <= int(v) <= 255 for v in values):
        raise ValueError(f"{what} must be 3 integers in 0-255 (RGB), got {color!r}")
    r, g, b = (int(v) for v in values)
    return r, g, b


def _check_size(size: tuple[int, int]) -> tuple[int, int]:
    if len(size) != 2 or any(int(v) != v for v in size):
        raise ValueError(f"size must be (width, height) in whole pixels, got {size!r}")
    width, height = int(size[0]), int(size[1])
    if width < _MIN_SIZE or height < _MIN_SIZE:
        raise ValueError(f"size must be at least {_MIN_SIZE} x {_MIN_SIZE} px (width, height), got {size!r}")
    return width, height


def _check_lim(lim: tuple[float, float], what: str, positive: bool = False) -> tuple[float, float]:
    if len(lim) != 2:
        raise ValueError(f"{what} must be (low, high), got {lim!r}")
    lo, hi = float(lim[0]), float(lim[1])
    if not (math.isfinite(lo) and math.isfinite(hi)) or lo >= hi:
        raise ValueError(f"{what} must be finite with low < high, got {lim!r}")
    if positive and lo <= 0:
        raise ValueError(f"{what} must be positive on a log axis, got {lim!r}")
    return lo, hi


def _check_legend_loc(loc: str) -> None:
    if loc not in LEGEND_LOCATIONS:
        raise ValueError(f"legend_loc must be one of {LEGEND_LOCATIONS}, got {loc!r}")


def _check_image(image: np.ndarray, what: str) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3 or 0 in image.shape:
        raise ValueError(f"{what} must be a non-empty RGB uint8 image (H, W, 3), got {image.dtype} {image.shape}")
    return image


# --------------------------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class _Frame:
    """Plot area in canvas pixels (left/right columns, top/bottom rows, inclusive) and the axis limits it
    shows (for a log axis the limits are log10 of the data)."""

    left: int
    top: int
    right: int
    bottom: int
    xlim: tuple[float, float]
    ylim: tuple[float, float]

    def px(self, x: np.ndarray | float) -> np.ndarray:
        return self.left + (np.asarray(x, np.float64) - self.xlim[0]) / (self.xlim[1] - self.xlim[0]) * (
            self.right - self.left)

    def py(self, y: np.ndarray | float) -> np.ndarray:
        return self.bottom - (np.asarray(y, np.float64) - self.ylim[0]) / (self.ylim[1] - self.ylim[0]) * (
            self.bottom - self.top)


def _clip_segment(p: np.ndarray, q: np.ndarray, rect: tuple[float, float, float, float]
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """Liang–Barsky clip of segment p→q (pixel (x, y)) to rect (x0, y0, x1, y1); None when outside."""
    x0, y0, x1, y1 = rect
    d = q - p
    t0, t1 = 0.0, 1.0
    # inside ⇔ num + t·den ≥ 0 for each (num, den): left, right, top, bottom edge
    for num, den in ((p[0] - x0, d[0]), (x1 - p[0], -d[0]), (p[1] - y0, d[1]), (y1 - p[1], -d[1])):
        if den == 0:
            if num < 0:
                return None
            continue
        t = -num / den
        if den > 0:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
        if t0 > t1:
            return None
    return p + t0 * d, p + t1 * d


def _fixed(p: np.ndarray) -> tuple[int, int]:
    """Pixel point as cv2 fixed-point coordinates (shift = 4)."""
    return round(float(p[0]) * 16), round(float(p[1]) * 16)


def _draw_path(img: np.ndarray, pts: np.ndarray, color: tuple[int, int, int], thick: int, dashed: bool,
               clip: tuple[float, float, float, float], dash: tuple[float, float]) -> None:
    """Draw the polyline ``pts`` (N, 2) pixel (x, y), clipped to ``clip``, solid or dashed with (on, off)
    lengths ``dash`` in px; the dash phase runs on along the path across vertices."""
    on, off = dash
    phase = 0.0  # distance travelled within the current on+off period
    for p, q in pairwise(pts):
        seg = _clip_segment(p, q, clip)
        if seg is None:
            continue
        a, b = seg
        if not dashed:
            cv2.line(img, _fixed(a), _fixed(b), color, thick, cv2.LINE_AA, shift=4)
            continue
        length = float(np.hypot(*(b - a)))
        s = 0.0
        while s < length:
            if phase < on:
                run = min(on - phase, length - s)
                u, v = a + (b - a) * (s / length), a + (b - a) * ((s + run) / length)
                cv2.line(img, _fixed(u), _fixed(v), color, thick, cv2.LINE_AA, shift=4)
            else:
                run = min(on + off - phase, length - s)
            s += run
            phase = (phase + run) % (on + off)


# --------------------------------------------------------------------------------------------- legend


@dataclass(frozen=True)
class _LegendEntry:
    label: str
    color: tuple[int, int, int]
    kind: str  # "line" or "patch"
    dashed: bool = False
    marker: bool = False


def _legend_metrics(entries: Sequence[_LegendEntry], st: _Style) -> tuple[int, int, list[int]]:
    """(sample width, row height, width of each entry) in px."""
    sample = 4 * st.pad if any(e.kind == "line" for e in entries) else round(1.8 * st.pad)
    heights = [_text_size(e.label, st.tick, st.text) for e in entries]
    row_h = max(h + b for _, h, b in heights) + st.pad // 2
    widths = [sample + st.pad // 2 + st.line + w for w, _, _ in heights]
    return sample, row_h, widths


def _draw_legend_entry(img: np.ndarray, e: _LegendEntry, x: int, y_mid: int, sample: int, st: _Style) -> None:
    if e.kind == "patch":
        half = max(3, round(0.6 * st.pad))
        cv2.rectangle(img, (x, y_mid - half), (x + sample, y_mid + half), e.color, -1)
    else:
        pts = np.array([[x, y_mid], [x + sample, y_mid]], np.float64)
        _draw_path(img, pts, e.color, st.line, e.dashed, (-1e9, -1e9, 1e9, 1e9), st.dash)
        if e.marker:
            cv2.circle(img, (x + sample // 2, y_mid), st.marker, e.color, -1, cv2.LINE_AA)
    _put_text(img, e.label, x + sample + st.pad // 2 + st.line, y_mid, st.tick, st.text, va="center")


def _legend_box_size(entries: Sequence[_LegendEntry], st: _Style) -> tuple[int, int]:
    _, row_h, widths = _legend_metrics(entries, st)
    return max(widths) + 2 * st.pad, row_h * len(entries) + st.pad


def _draw_legend_box(img: np.ndarray, entries: Sequence[_LegendEntry], x: int, y: int, st: _Style) -> None:
    """Legend as a bordered white box with its top-left corner at (x, y), one entry per row."""
    sample, row_h, _ = _legend_metrics(entries, st)
    w, h = _legend_box_size(entries, st)
    cv2.rectangle(img, (x, y), (x + w, y + h), _WHITE, -1)
    cv2.rectangle(img, (x, y), (x + w, y + h), _LEGEND_EDGE, 1)
    for i, e in enumerate(entries):
        _draw_legend_entry(img, e, x + st.pad, y + st.pad // 2 + i * row_h + row_h // 2, sample, st)


def _legend_rows(entries: Sequence[_LegendEntry], max_width: int, st: _Style) -> list[list[int]]:
    """Entry indices flowed into rows no wider than ``max_width`` px (an over-wide entry gets its own row)."""
    _, _, widths = _legend_metrics(entries, st)
    gap = 2 * st.pad
    rows: list[list[int]] = [[]]
    used = 0
    for i, w in enumerate(widths):
        if rows[-1] and used + gap + w > max_width:
            rows.append([])
            used = 0
        used += (gap if rows[-1] else 0) + w
        rows[-1].append(i)
    return rows


def _outside_legend_height(entries: Sequence[_LegendEntry], max_width: int, st: _Style) -> int:
    if not entries:
        return 0
    _, row_h, _ = _legend_metrics(entries, st)
    return row_h * len(_legend_rows(entries, max_width, st)) + st.pad // 2


def _draw_outside_legend(img: np.ndarray, entries: Sequence[_LegendEntry], left: int, right: int, top: int,
                         st: _Style) -> None:
    """Legend rows centred over columns [left, right], starting at row ``top``."""
    sample, row_h, widths = _legend_metrics(entries, st)
    gap = 2 * st.pad
    for r, row in enumerate(_legend_rows(entries, right - left, st)):
        total = sum(widths[i] for i in row) + gap * (len(row) - 1)
        x = (left + right - total) // 2
        for i in row:
            _draw_legend_entry(img, entries[i], x, top + r * row_h + row_h // 2, sample, st)
            x += widths[i] + gap


def _inside_legend_origin(loc: str, box: tuple[int, int], frame: _Frame, st: _Style,
                          data_pts: np.ndarray) -> tuple[int, int]:
    """Top-left pixel of an inside legend box of size ``box`` (w, h) at corner ``loc``; for ``"best"`` the
    corner whose box holds the fewest of ``data_pts`` (N, 2) pixel (x, y)."""
    w, h = box
    inset = st.pad
    corners = {
        "upper left": (frame.left + inset, frame.top + inset),
        "upper right": (frame.right - inset - w, frame.top + inset),
        "lower right": (frame.right - inset - w, frame.bottom - inset - h),
        "lower left": (frame.left + inset, frame.bottom - inset - h),
    }
    if loc != "best":
        return corners[loc]
    best_loc, best_n = "upper left", None
    for name, (x, y) in corners.items():
        n = 0
        if len(data_pts):
            m = st.marker + st.line
            inside = ((data_pts[:, 0] >= x - m) & (data_pts[:, 0] <= x + w + m)
                      & (data_pts[:, 1] >= y - m) & (data_pts[:, 1] <= y + h + m))
            n = int(inside.sum())
        if best_n is None or n < best_n:
            best_loc, best_n = name, n
    return corners[best_loc]


def _densify(pts: np.ndarray, spacing: float = 3.0) -> np.ndarray:
    """Points every ~``spacing`` px along the polyline ``pts`` (N, 2) (used to score legend placement)."""
    out = [pts]
    for p, q in pairwise(pts):
        n = min(int(np.hypot(*(q - p)) / spacing), 2000)
        if n > 1:
            t = np.linspace(0.0, 1.0, n)[:, None]
            out.append(p + t * (q - p))
    return np.concatenate(out)


# --------------------------------------------------------------------------------------------- axes


def _draw_title(img: np.ndarray, title: str, st: _Style) -> int:
    """Title centred at the top; returns the first free row below it."""
    if not title:
        return st.pad
    scale = _fit_scale([title], st.title, st.title_text, img.shape[1] - 2 * st.pad, 0.3)
    _, h, base = _text_size(title, scale, st.title_text)
    _put_text(img, title, img.shape[1] / 2, st.pad, scale, st.title_text, ha="center", va="top")
    return st.pad + h + base + st.pad


def _draw_frame(img: np.ndarray, f: _Frame) -> None:
    cv2.rectangle(img, (f.left, f.top), (f.right, f.bottom), _FRAME, 1)


def _draw_y_axis(img: np.ndarray, f: _Frame, values: np.ndarray, labels: Sequence[str], st: _Style,
                 minor: np.ndarray | None = None) -> None:
    """Horizontal grid lines, tick marks and right-aligned labels at data values (already transformed to
    the frame's y space)."""
    if minor is not None:
        for v in minor:
            y = round(float(f.py(v)))
            cv2.line(img, (f.left + 1, y), (f.right - 1, y), _MINOR_GRID, 1)
    for v, text in zip(values, labels):
        y = round(float(f.py(v)))
        cv2.line(img, (f.left + 1, y), (f.right - 1, y), _GRID, 1)
        cv2.line(img, (f.left - st.tick_len, y), (f.left, y), _FRAME, 1)
        _put_text(img, text, f.left - st.tick_len - st.pad // 2, y, st.tick, st.text, ha="right", va="center")


def _draw_x_axis(img: np.ndarray, f: _Frame, values: np.ndarray, labels: Sequence[str], st: _Style) -> None:
    for v, text in zip(values, labels):
        x = round(float(f.px(v)))
        cv2.line(img, (x, f.top + 1), (x, f.bottom - 1), _GRID, 1)
        cv2.line(img, (x, f.bottom), (x, f.bottom + st.tick_len), _FRAME, 1)
        _put_text(img, text, x, f.bottom + st.tick_len + st.pad // 2, st.tick, st.text, ha="center", va="top")


def _draw_axis_labels(canvas: np.ndarray, xlabel: str, ylabel: str, frame, st) -> None:
    """The rotated y-axis label left of ``frame`` and the x-axis label centred under it."""
    _draw_ylabel(canvas, ylabel, frame, st)
    if xlabel:
        _put_text(canvas, xlabel, (frame.left + frame.right) / 2, canvas.shape[0] - 1 - st.pad // 2, st.label,
                  st.text, ha="center", va="bottom")


def _draw_ylabel(img: np.ndarray, ylabel: str, f: _Frame, st: _Style) -> None:
    if not ylabel:
        return
    scale = _fit_scale([ylabel], st.label, st.text, f.bottom - f.top + 2 * st.pad, 0.3)
    tile = _vertical_text(ylabel, scale, st.text)
    _paste_darker(img, tile, st.pad, (f.top + f.bottom) // 2 - tile.shape[0] // 2)


def _ylabel_width(ylabel: str, st: _Style) -> int:
    if not ylabel:
        return 0
    _, h, base = _text_size(ylabel, st.label, st.text)
    return h + base + 2 + st.pad


# --------------------------------------------------------------------------------------------- line chart


def line_panel(series: Sequence[Series], *, title: str, xlabel: str, ylabel: str, size: tuple[int, int] = (640, 480),
               ylim: tuple[float, float] | None = None, log_y: bool = False,
               legend_loc: str = "best") -> np.ndarray:
    """One line chart as a (height, width, 3) RGB uint8 image, with ``size`` = (width, height) in px.

    Axes: linear x; y linear or, with ``log_y``, log10 with ticks at decades. Limits come from the data
    (y ignoring NaN gaps) with ~5 % padding, moved outward to a nice tick value when that adds little;
    ``ylim`` = (low, high) in data units overrides y (lines are clipped to the plot area). The legend lists
    series with a non-empty label, at ``legend_loc`` (see ``LEGEND_LOCATIONS``). Raises ``ValueError`` for
    no series, a series with no finite y anywhere, non-positive y (or ylim) with ``log_y``, a bad ``ylim``,
    ``legend_loc`` or ``size`` (at least 64 px a side, and room left for a plot after the labels)."""
    width, height = _check_size(size)
    if len(series) == 0:
        raise ValueError("line_panel needs at least one series")
    for s in series:
        if not isinstance(s, Series):
            raise TypeError(f"line_panel expects Series, got {type(s).__name__}")
    _check_legend_loc(legend_loc)
    st = _Style.for_size(width, height)

    xs = np.concatenate([np.asarray(s.x) for s in series])
    ys = np.concatenate([np.asarray(s.y) for s in series])
    ys = ys[np.isfinite(ys)]
    if ys.size == 0:
        raise ValueError("line_panel: no finite y values to plot")
    if log_y and (ys <= 0).any():
        raise ValueError(f"log_y needs positive y values, got minimum {ys.min()}")
    xlim = _linear_limits(float(xs.min()), float(xs.max()))
    if ylim is not None:
        lo, hi = _check_lim(ylim, "ylim", positive=log_y)
        ylim_t = (math.log10(lo), math.log10(hi)) if log_y else (lo, hi)
    elif log_y:
        lo_l, hi_l = _widen(math.log10(float(ys.min())), math.log10(float(ys.max())))
        if hi_l - lo_l < 1:  # show at least one decade, centred on the data
            mid = (lo_l + hi_l) / 2
            lo_l, hi_l = mid - 0.5, mid + 0.5
        ylim_t = _snap_limits(lo_l, hi_l, (1.0,))
    else:
        ylim_t = _linear_limits(float(ys.min()), float(ys.max()))

    entries = [_LegendEntry(s.label, s.color, "line", s.dashed, s.marker) for s in series if s.label]
    legend_top = 0
    canvas = np.full((height, width, 3), 255, np.uint8)

    # vertical layout: title, [outside legend], plot, x tick labels, x label
    top = _draw_title(canvas, title, st)
    _, tick_h, tick_base = _text_size("0123456789", st.tick, st.text)
    bottom_margin = st.tick_len + st.pad // 2 + tick_h + tick_base + st.pad
    if xlabel:
        _, lh, lb = _text_size(xlabel, st.label, st.text)
        bottom_margin += lh + lb + st.pad // 2
    if legend_loc == "outside" and entries:
        legend_top = top
        top += _outside_legend_height(entries, width - 2 * st.pad, st)
    top = max(top, st.pad + tick_h // 2 + 1)
    plot_bottom = height - 1 - bottom_margin
    plot_h = plot_bottom - top

    # y ticks, then the left margin they need, then x ticks
    def text_w(t: str) -> float:
        return _text_size(t, st.tick, st.text)[0]

    def text_h(t: str) -> float:
        return tick_h + tick_base

    yminor_t: np.ndarray | None = None
    if log_y:
        major, minor = _pick_log_ticks(ylim_t[0], ylim_t[1], max(plot_h, 1), 1.5 * (tick_h + tick_base), text_h)
        ytick_t = np.log10(major)
        yminor_t = np.log10(minor) if len(minor) else None
        ytick_labels = [_format_log_tick(float(v)) for v in major]
    else:
        ytick_t, ytick_labels = _pick_linear_ticks(ylim_t[0], ylim_t[1], max(plot_h, 1), text_h, tick_h + tick_base)
    ytick_w = max((text_w(t) for t in ytick_labels), default=0)
    left = st.pad + _ylabel_width(ylabel, st) + ytick_w + st.pad // 2 + st.tick_len
    est_right = width - 1 - 2 * st.pad
    xticks, xtick_labels = _pick_linear_ticks(xlim[0], xlim[1], max(est_right - left, 1), text_w, 2 * st.pad)
    last_w = _text_size(xtick_labels[-1], st.tick, st.text)[0] if xtick_labels else 0
    right = width - 1 - max(2 * st.pad, last_w // 2 + st.pad // 2)
    if right - left < _MIN_PLOT or plot_h < _MIN_PLOT:
        raise ValueError(f"size {size} leaves no room for the plot area after the labels")
    frame = _Frame(left, top, right, plot_bottom, xlim, ylim_t)

    _draw_y_axis(canvas, frame, ytick_t, ytick_labels, st, yminor_t)
    _draw_x_axis(canvas, frame, xticks, xtick_labels, st)

    # data: lines clipped to the plot area, markers allowed to overhang it by their radius
    clip = (frame.left + 0.5, frame.top + 0.5, frame.right - 0.5, frame.bottom - 0.5)
    m = st.marker + 1
    scored: list[np.ndarray] = []
    for s in series:
        y = np.asarray(s.y)
        ok = np.isfinite(y)
        y_t = np.log10(np.where(ok, y, 1.0)) if log_y else y
        pts = np.stack([frame.px(np.asarray(s.x)), frame.py(y_t)], axis=1)
        runs = np.split(np.arange(len(y)), np.flatnonzero(np.diff(ok.astype(np.int8))) + 1)
        for run in runs:
            if not ok[run[0]]:
                continue
            p = pts[run]
            _draw_path(canvas, p, s.color, st.line, s.dashed, clip, st.dash)
            scored.append(_densify(p))
            if s.marker or len(run) == 1:
                for q in p:
                    if frame.left - m <= q[0] <= frame.right + m and frame.top - m <= q[1] <= frame.bottom + m:
                        cv2.circle(canvas, _fixed(q), st.marker * 16, s.color, -1, cv2.LINE_AA, shift=4)
    _draw_frame(canvas, frame)

    _draw_axis_labels(canvas, xlabel, ylabel, frame, st)
    if entries:
        if legend_loc == "outside":
            _draw_outside_legend(canvas, entries, frame.left, frame.right, legend_top, st)
        else:
            box = _legend_box_size(entries, st)
            data_pts = np.concatenate(scored) if scored else np.zeros((0, 2))
            x, y = _inside_legend_origin(legend_loc, box, frame, st, data_pts)
            _draw_legend_box(canvas, entries, x, y, st)
    return canvas


# --------------------------------------------------------------------------------------------- bar chart


def _wrap(text: str, scale: float, thick: int, max_width: float) -> list[str]:
    """``text`` split at spaces into lines of at most ``max_width`` px where possible."""
    lines: list[str] = []
    for word in text.split():
        if lines and _text_size(f"{lines[-1]} {word}", scale, thick)[0] <= max_width:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines or [""]


def bar_chart(groups: Sequence[str], series_labels: Sequence[str], bars: Sequence[Sequence[Bar | None]],
              colors: Sequence[tuple[int, int, int]], *, title: str, ylabel: str, size: tuple[int, int] = (900, 480),
              ylim: tuple[float, float] | None = None, xlabel: str = "", legend_loc: str = "outside") -> np.ndarray:
    """Grouped bar chart as a (height, width, 3) RGB uint8 image, with ``size`` = (width, height) in px.

    ``bars[g][s]`` is series ``s`` in group ``groups[g]`` (None = missing: nothing is drawn), coloured
    ``colors[s]`` (RGB; extra colours are ignored), with a dark whisker from ``low`` to ``high`` (with caps)
    and its ``label`` above it. Bars start at 0 in data units; the auto y range includes 0, the whiskers
    and room for the labels, and ``ylim`` = (low, high) overrides it (bars and whiskers are clipped).
    Group names are centred under their groups (wrapped at spaces, shrunk if needed); the legend shows
    ``series_labels`` at ``legend_loc`` (default ``"outside"``: a row above the plot). Raises ``ValueError``
    for no groups or series, mismatched lengths, too few colours, a bad ``ylim``, ``legend_loc`` or
    ``size``."""
    width, height = _check_size(size)
    n_groups, n_series = len(groups), len(series_labels)
    if n_groups == 0 or n_series == 0:
        raise ValueError("bar_chart needs at least one group and one series")
    if len(bars) != n_groups:
        raise ValueError(f"bar_chart: {n_groups} groups but {len(bars)} rows of bars")
    for g, row in enumerate(bars):
        if len(row) != n_series:
            raise ValueError(f"bar_chart: group {groups[g]!r} has {len(row)} bars for {n_series} series")
        for b in row:
            if b is not None and not isinstance(b, Bar):
                raise TypeError(f"bar_chart expects Bar or None, got {type(b).__name__}")
    if len(colors) < n_series:
        raise ValueError(f"bar_chart: {len(colors)} colours for {n_series} series")
    cols = [_check_color(c, f"colour of series {series_labels[i]!r}") for i, c in enumerate(colors[:n_series])]
    _check_legend_loc(legend_loc)
    st = _Style.for_size(width, height)
    present = [b for row in bars for b in row if b is not None]

    canvas = np.full((height, width, 3), 255, np.uint8)
    entries = [_LegendEntry(str(lbl), cols[i], "patch") for i, lbl in enumerate(series_labels) if lbl]
    top = _draw_title(canvas, title, st)
    legend_top = top
    if legend_loc == "outside" and entries:
        top += _outside_legend_height(entries, width - 2 * st.pad, st)
    _, tick_h, tick_base = _text_size("0123456789", st.tick, st.text)
    top = max(top, st.pad + tick_h // 2 + 1)

    # y limits (the group label rows below need the plot width, which needs the y tick labels: estimate)
    est_bottom = height - 1 - (st.tick_len + 2 * (tick_h + tick_base) + 3 * st.pad)
    est_plot_h = max(est_bottom - top, 1)
    if ylim is not None:
        ylim_v = _check_lim(ylim, "ylim")
    else:
        lows = [min(b.value, b.low if b.low is not None else b.value) for b in present]
        highs = [max(b.value, b.high if b.high is not None else b.value) for b in present]
        lo, hi = min([0.0, *lows]), max([0.0, *highs])
        if lo == hi:  # nothing, or only zero-height bars
            lo, hi = (0.0, 1.0)
        # room for value labels beyond the bar ends, as a fraction of the data span
        room = (tick_h + tick_base + st.pad) / est_plot_h
        label_up = any(b.label and b.value >= 0 for b in present)
        label_down = any(b.label and b.value < 0 for b in present)
        step = _tick_step(lo, hi)
        ylim_v = _snap_limits(lo, hi, (step, step / 2),
                              pad_lo=(0.05 if lo < 0 else 0.0) + (room if label_down else 0.0),
                              pad_hi=(0.05 if hi > 0 else 0.0) + (room if label_up else 0.0))

    def text_h(t: str) -> float:
        return tick_h + tick_base

    ticks, ytick_labels = _pick_linear_ticks(ylim_v[0], ylim_v[1], est_plot_h, text_h, tick_h + tick_base)
    ytick_w = max((_text_size(t, st.tick, st.text)[0] for t in ytick_labels), default=0)
    left = st.pad + _ylabel_width(ylabel, st) + ytick_w + st.pad // 2 + st.tick_len
    right = width - 1 - 2 * st.pad
    group_w = (right - left) / n_groups

    # group names: wrapped to the group width, one common (possibly reduced) font scale
    names = [str(g) for g in groups]
    words = [w for name in names for w in name.split()]
    gscale = _fit_scale(words or [""], st.label, st.text, group_w - st.pad, 0.3)
    wrapped = [_wrap(name, gscale, st.text, group_w - st.pad) for name in names]
    _, gh, gb = _text_size("Ag", gscale, st.text)
    line_h = gh + gb + 2
    n_lines = max(len(w) for w in wrapped)
    bottom_margin = st.tick_len + st.pad // 2 + n_lines * line_h + st.pad
    if xlabel:
        _, xh, xb = _text_size(xlabel, st.label, st.text)
        bottom_margin += xh + xb + st.pad // 2
    plot_bottom = height - 1 - bottom_margin
    if right - left < _MIN_PLOT or plot_bottom - top < _MIN_PLOT:
        raise ValueError(f"size {size} leaves no room for the plot area after the labels")
    frame = _Frame(left, top, right, plot_bottom, (0.0, float(n_groups)), ylim_v)
    _draw_y_axis(canvas, frame, ticks, ytick_labels, st)

    # bars, whiskers, value labels
    inner = 0.8 * group_w
    bar_w = inner / n_series
    gap = 1 if bar_w < 8 else max(1, round(0.08 * bar_w))
    label_scale = _fit_scale([b.label for b in present if b.label] or [""], st.tick, st.text,
                             bar_w + gap, 0.25)
    y_base = float(np.clip(frame.py(0.0), frame.top, frame.bottom))
    for g, row in enumerate(bars):
        for s, b in enumerate(row):
            if b is None:
                continue
            x0 = left + g * group_w + 0.1 * group_w + s * bar_w
            xa, xb = round(x0 + gap / 2), round(x0 + bar_w - gap / 2) - 1
            xb = max(xa, xb)
            y_top = float(np.clip(frame.py(b.value), frame.top, frame.bottom))
            ya, yb = sorted((round(y_top), round(y_base)))
            if b.value != 0:
                cv2.rectangle(canvas, (xa, ya), (xb, yb), cols[s], -1)
            xc = (xa + xb) / 2
            extent = [b.value]
            if b.low is not None or b.high is not None:
                lo_w = b.low if b.low is not None else b.value
                hi_w = b.high if b.high is not None else b.value
                extent += [lo_w, hi_w]
                cap = max(2.0, min(0.25 * bar_w, 3.0 * st.pad))
                wt = max(1, round(st.line * 0.6))
                ends = [float(frame.py(v)) for v in (lo_w, hi_w)]
                clip = (frame.left, frame.top, frame.right, frame.bottom)
                _draw_path(canvas, np.array([[xc, ends[0]], [xc, ends[1]]]), _WHISKER, wt, False, clip, (1, 1))
                for yv in ends:
                    if frame.top <= yv <= frame.bottom:
                        _draw_path(canvas, np.array([[xc - cap, yv], [xc + cap, yv]]), _WHISKER, wt, False, clip,
                                   (1, 1))
            if b.label:
                if b.value >= 0:
                    yl = float(frame.py(max(extent))) - st.pad // 2 - st.line
                    va = "bottom"
                else:
                    yl = float(frame.py(min(extent))) + st.pad // 2 + st.line
                    va = "top"
                yl = float(np.clip(yl, frame.top + tick_h + 1, frame.bottom - 1)) if va == "bottom" else yl
                _put_text(canvas, b.label, xc, yl, label_scale, st.text, ha="center", va=va)
    if frame.top < y_base < frame.bottom:  # zero line inside the range
        cv2.line(canvas, (frame.left, round(y_base)), (frame.right, round(y_base)), _FRAME, 1)
    _draw_frame(canvas, frame)

    for g, lines in enumerate(wrapped):
        xc = left + (g + 0.5) * group_w
        for i, text in enumerate(lines):
            _put_text(canvas, text, xc, frame.bottom + st.tick_len + st.pad // 2 + i * line_h, gscale, st.text,
                      ha="center", va="top")
        if g:
            xs = round(left + g * group_w)
            cv2.line(canvas, (xs, frame.bottom), (xs, frame.bottom + st.tick_len), _FRAME, 1)
    _draw_axis_labels(canvas, xlabel, ylabel, frame, st)
    if entries:
        if legend_loc == "outside":
            _draw_outside_legend(canvas, entries, frame.left, frame.right, legend_top, st)
        else:
            rects = []
            for g, row in enumerate(bars):
                for s, b in enumerate(row):
                    if b is not None:
                        x0 = left + g * group_w + 0.1 * group_w + (s + 0.5) * bar_w
                        top_v = max(b.value, b.high if b.high is not None else b.value)
                        ys_ = np.linspace(float(frame.py(top_v)) - tick_h - st.pad, y_base, 12)
                        rects.append(np.stack([np.full_like(ys_, x0), ys_], axis=1))
            data_pts = np.concatenate(rects) if rects else np.zeros((0, 2))
            x, y = _inside_legend_origin(legend_loc, _legend_box_size(entries, st), frame, st, data_pts)
            _draw_legend_box(canvas, entries, x, y, st)
    return canvas


# --------------------------------------------------------------------------------------------- composition, I/O


def _check_stack(images: Sequence[np.ndarray], gap: int) -> list[np.ndarray]:
    if len(images) == 0:
        raise ValueError("nothing to stack: no images")
    if int(gap) != gap or gap < 0:
        raise ValueError(f"gap must be a non-negative whole number of px, got {gap!r}")
    return [_check_image(img, f"image {i}") for i, img in enumerate(images)]


def hstack(images: Sequence[np.ndarray], gap: int = 0) -> np.ndarray:
    """Images (H_i, W_i, 3) RGB uint8 side by side, left to right, top-aligned, shorter ones padded with
    white at the bottom, ``gap`` white px between neighbours. Raises ``ValueError`` for no images, a
    non-RGB-uint8 image or a negative gap."""
    imgs = _check_stack(images, gap)
    h = max(img.shape[0] for img in imgs)
    parts: list[np.ndarray] = []
    for i, img in enumerate(imgs):
        if i and gap:
            parts.append(np.full((h, int(gap), 3), 255, np.uint8))
        pad = np.full((h - img.shape[0], img.shape[1], 3), 255, np.uint8)
        parts.append(np.concatenate([img, pad], axis=0))
    return np.concatenate(parts, axis=1)


def vstack(images: Sequence[np.ndarray], gap: int = 0) -> np.ndarray:
    """Images (H_i, W_i, 3) RGB uint8 one below the other, top to bottom, left-aligned, narrower ones padded
    with white on the right, ``gap`` white px between neighbours. Raises ``ValueError`` like ``hstack``."""
    imgs = _check_stack(images, gap)
    w = max(img.shape[1] for img in imgs)
    parts: list[np.ndarray] = []
    for i, img in enumerate(imgs):
        if i and gap:
            parts.append(np.full((int(gap), w, 3), 255, np.uint8))
        pad = np.full((img.shape[0], w - img.shape[1], 3), 255, np.uint8)
        parts.append(np.concatenate([img, pad], axis=1))
    return np.concatenate(parts, axis=0)


def save_png(path: str | os.PathLike[str], image: np.ndarray) -> None:
    """Write an RGB uint8 (H, W, 3) image to ``path`` as PNG (converted to OpenCV's BGR order), atomically:
    the bytes go to a temporary file in the same directory, are fsynced and renamed over ``path`` with
    ``os.replace`` (mode 0644), so ``path`` is the old file or the whole new one, never a part. Raises
    ``ValueError`` for a non-RGB-uint8 image or when OpenCV fails to encode it; missing folders are created."""
    image = _check_image(image, "image")
    ok, buf = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    if not ok:
        raise ValueError(f"OpenCV could not encode a PNG for {path}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda f: f.write(buf.tobytes()))
