import math

import cv2
import numpy as np
import pytest

from kgn_bench.viz.plot import (
    PALETTE_RGB,
    Bar,
    Series,
    _format_tick,
    bar_chart,
    hstack,
    line_panel,
    nice_ticks,
    save_png,
    vstack,
)

RED, BLUE = (214, 39, 40), (31, 119, 180)
FRAME = (50, 50, 50)  # the axes box colour drawn by plot.py


def color_mask(img, color, tol=40):
    return np.abs(img.astype(np.int32) - np.array(color)).sum(axis=2) <= tol


def tinted(img, color, strength=0.35):
    """Pixels whose ink (255 - value) is at least ``strength`` of the colour's ink and points its way, i.e.
    the colour antialiased onto white (grey grid lines and black text do not qualify)."""
    ink = 255.0 - img.astype(np.float64)
    c = 255.0 - np.array(color, np.float64)
    k = ink @ c / (c @ c)
    residual = np.linalg.norm(ink - k[..., None] * c, axis=2)
    return (k >= strength) & (residual <= 6 + 0.05 * k * np.linalg.norm(c))


def frame_box(img):
    """(top, bottom, left, right) of the axes box: the rows / columns mostly in the exact frame colour."""
    m = (img == np.array(FRAME, np.uint8)).all(axis=2)
    rows = np.flatnonzero(m.sum(axis=1) > 0.5 * img.shape[1] * 0.5)
    cols = np.flatnonzero(m.sum(axis=0) > 0.5 * img.shape[0] * 0.5)
    return rows.min(), rows.max(), cols.min(), cols.max()


@pytest.mark.parametrize("lo, hi", [(0, 1), (0.13, 0.87), (-3.7, 12.2), (1e-5, 3.2e-5), (0, 100), (1, 40),
                                    (-250, -3), (123456, 123999)])
def test_nice_ticks_are_even_1_2_5_steps_covering_the_range(lo, hi):
    ticks = nice_ticks(lo, hi)
    assert 3 <= len(ticks) <= 10
    steps = np.diff(ticks)
    step = steps[0]
    assert np.allclose(steps, step, rtol=1e-9, atol=0)
    mantissa = step / 10.0 ** math.floor(math.log10(step) + 1e-12)
    assert min(abs(mantissa - m) for m in (1, 2, 5)) < 1e-9
    tol = 1e-9 * step
    assert ticks[0] <= lo + tol and ticks[-1] >= hi - tol
    assert ticks[0] > lo - step - tol and ticks[-1] < hi + step + tol  # no more than one step beyond
    assert np.allclose(ticks / step, np.round(ticks / step), atol=1e-6)  # multiples of the step


def test_nice_ticks_values_are_clean_and_bad_ranges_rejected():
    assert nice_ticks(0, 0.6, 7).tolist() == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6]  # 0.3, not 0.30000000000000004
    single = nice_ticks(5, 5)  # widened around the value
    assert single[0] < 5 < single[-1] and np.allclose(np.diff(single), single[1] - single[0])
    with pytest.raises(ValueError):
        nice_ticks(2, 1)
    with pytest.raises(ValueError):
        nice_ticks(0, float("nan"))
    with pytest.raises(ValueError):
        nice_ticks(0, 1, target=1)


def test_tick_labels_drop_trailing_zeros():
    assert [_format_tick(v, 0.5) for v in (0.0, 0.5, 1.0, 1.5, 10.0)] == ["0", "0.5", "1", "1.5", "10"]
    assert _format_tick(0.25, 0.05) == "0.25"
    assert _format_tick(-0.0, 0.2) == "0"
    assert _format_tick(2e6, 1e6) == "2e6"


def test_line_panel_shape_and_a_rising_series_rises():
    x = np.linspace(0, 10, 30)
    img = line_panel([Series("", x, 3 * x + 1, RED)], title="rising", xlabel="x (m)", ylabel="y (m)", size=(500, 350))
    assert img.shape == (350, 500, 3) and img.dtype == np.uint8
    top, bottom, left, right = frame_box(img)
    assert 0 < left < right < 500 and 0 < top < bottom < 350
    rows, cols = np.nonzero(color_mask(img, RED))
    assert len(rows) > 100
    # every pixel of the series' colour lies in the plot area (the marker may overhang the frame a little)
    assert rows.min() >= top - 6 and rows.max() <= bottom + 6 and cols.min() >= left - 6 and cols.max() <= right + 6
    third = (cols.max() - cols.min()) / 3
    left_rows = rows[cols < cols.min() + third]
    right_rows = rows[cols > cols.max() - third]
    assert right_rows.mean() < left_rows.mean() - 50  # higher (smaller row) on the right


def largest_column_gap(img, color):
    cols = np.unique(np.nonzero(tinted(img, color))[1])
    return np.diff(cols).max() / (cols.max() - cols.min())


def test_nan_points_break_the_line():
    x = [0, 1, 2, 3, 4, 5, 6]
    y = [np.nan, 1.0, 2.0, np.nan, np.nan, 2.5, 3.0]
    kw = dict(title="", xlabel="", ylabel="", size=(400, 300))
    gappy = line_panel([Series("", x, y, BLUE, marker=False)], **kw)
    full = line_panel([Series("", x, np.nan_to_num(y, nan=2.0), BLUE, marker=False)], **kw)
    assert largest_column_gap(gappy, BLUE) > 0.3  # nothing drawn from x = 2 to x = 5
    assert largest_column_gap(full, BLUE) < 0.05
    # an isolated point between gaps is still visible, and an all-NaN series next to a real one is fine
    lone = line_panel([Series("", [0, 1, 2], [np.nan, 1.8, np.nan], RED, marker=False),
                       Series("", [0, 2], [0.0, 2.0], BLUE), Series("", [0, 2], [np.nan, np.nan], RED)], **kw)
    assert tinted(lone, RED, strength=0.9).sum() > 12


def test_dashed_line_has_fewer_coloured_pixels_than_solid():
    x = np.arange(10.0)
    kw = dict(title="t", xlabel="x", ylabel="y", size=(400, 300))
    solid = line_panel([Series("", x, np.sin(x), RED, marker=False)], **kw)
    dashed = line_panel([Series("", x, np.sin(x), RED, dashed=True, marker=False)], **kw)
    n_solid, n_dashed = tinted(solid, RED).sum(), tinted(dashed, RED).sum()
    assert 0.3 * n_solid < n_dashed < 0.8 * n_solid


def test_log_y_and_ylim():
    img = line_panel([Series("a", [1, 2, 3], [1e-3, 1e-1, 10.0], RED)], title="log", xlabel="x", ylabel="y",
                     log_y=True)
    rows, cols = np.nonzero(color_mask(img, RED))
    assert len(rows) > 0
    # on a log axis 1e-3 → 1e-1 → 10 are evenly spaced: the middle marker sits halfway between the others
    # (legend excluded: it is placed away from the data, in the top left/right corner)
    img2 = line_panel([Series("", [1, 2, 3], [1e-3, 1e-1, 10.0], RED, marker=False)], title="", xlabel="",
                      ylabel="", log_y=True)
    rows, cols = np.nonzero(color_mask(img2, RED))
    mid = rows[np.abs(cols - (cols.min() + cols.max()) / 2) <= 1].mean()
    assert abs(mid - (rows.min() + rows.max()) / 2) < 4
    with pytest.raises(ValueError):
        line_panel([Series("a", [1, 2], [1.0, 0.0], RED)], title="", xlabel="", ylabel="", log_y=True)
    with pytest.raises(ValueError):
        line_panel([Series("a", [1, 2], [1.0, 2.0], RED)], title="", xlabel="", ylabel="", log_y=True, ylim=(0, 3))
    # ylim clips: a series far outside the range still draws only inside the frame
    img3 = line_panel([Series("", [0, 1, 2], [0.5, 1e9, 0.5], RED)], title="", xlabel="", ylabel="", ylim=(0, 1))
    top, _, _, _ = frame_box(img3)
    assert np.nonzero(color_mask(img3, RED))[0].min() >= top - 6


def test_best_legend_avoids_the_data():
    x = np.linspace(0, 1, 20)
    img = line_panel([Series("falling", x, 1 - x, RED)], title="", xlabel="", ylabel="", legend_loc="best")
    _, _, left, right = frame_box(img)
    legend_cols = np.nonzero((img == np.array((190, 190, 190), np.uint8)).all(axis=2))[1]
    assert legend_cols.size > 0 and legend_cols.mean() > (left + right) / 2  # upper left is taken: goes right


def test_bad_series_and_panels_raise():
    with pytest.raises(ValueError):
        line_panel([], title="", xlabel="", ylabel="")
    with pytest.raises(ValueError):
        Series("empty", [], [], RED)
    with pytest.raises(ValueError):
        Series("mismatch", [1, 2, 3], [1, 2], RED)
    with pytest.raises(ValueError):
        Series("inf", [1, 2], [1, np.inf], RED)
    with pytest.raises(ValueError):
        Series("nan x", [1, np.nan], [1, 2], RED)
    with pytest.raises(ValueError):
        Series("colour", [1], [1], (0, 0, 300))
    with pytest.raises(ValueError):
        line_panel([Series("all nan", [1, 2], [np.nan, np.nan], RED)], title="", xlabel="", ylabel="")
    with pytest.raises(ValueError):
        line_panel([Series("a", [1], [1], RED)], title="", xlabel="", ylabel="", size=(-640, 480))
    with pytest.raises(ValueError):
        line_panel([Series("a", [1], [1], RED)], title="", xlabel="", ylabel="", legend_loc="middle")
    s = Series("ok", np.arange(3), np.ones(3), np.array(RED))
    assert s.x == (0.0, 1.0, 2.0) and s.color == RED and isinstance(s.y, tuple)


def test_bar_heights_whiskers_and_missing_bars():
    groups = ["tall", "short"]
    img = bar_chart(groups, ["s"], [[Bar(8.0)], [Bar(2.0)]], [RED], title="bars", ylabel="n")
    assert img.shape == (480, 900, 3) and img.dtype == np.uint8
    m = color_mask(img, RED, tol=0)
    top, bottom, left, right = frame_box(img)
    mid = (left + right) // 2
    inside = m[top + 1 : bottom, :]
    assert inside[:, :mid].sum() > 3 * inside[:, mid:].sum() > 0  # 8 vs 2

    img = bar_chart(["g"], ["whisker", "plain", "missing"], [[Bar(5.0, 4.0, 7.0), Bar(5.0), None]],
                    [RED, BLUE, PALETTE_RGB[2]], title="", ylabel="")
    top, bottom, left, right = frame_box(img)
    dark = (img < 90).all(axis=2)
    for color, whisker in ((RED, True), (BLUE, False)):
        m = color_mask(img, color, tol=0)
        m[: top + 1] = False  # the legend patches above the plot
        rows, cols = np.nonzero(m)
        bar_top = rows.min()
        col_band = slice(cols.min(), cols.max() + 1)
        above = dark[top + 2 : bar_top - 1, col_band]
        assert above.any() == whisker
    # the missing bar draws nothing in the plot area, though its series is in the legend above it
    green = color_mask(img, PALETTE_RGB[2], tol=0)
    assert not green[top:bottom].any() and green[:top].any()


def test_bad_bar_charts_raise():
    with pytest.raises(ValueError):
        bar_chart([], ["s"], [], [RED], title="", ylabel="")
    with pytest.raises(ValueError):
        bar_chart(["a", "b"], ["s"], [[Bar(1.0)]], [RED], title="", ylabel="")
    with pytest.raises(ValueError):
        bar_chart(["a"], ["s", "t"], [[Bar(1.0)]], [RED], title="", ylabel="")
    with pytest.raises(ValueError):
        bar_chart(["a"], ["s", "t"], [[Bar(1.0), Bar(2.0)]], [RED], title="", ylabel="")  # one colour, 2 series
    with pytest.raises(ValueError):
        Bar(1.0, low=2.0, high=1.0)
    with pytest.raises(ValueError):
        Bar(float("nan"))


def test_stacking_pads_with_white():
    a = np.zeros((10, 4, 3), np.uint8)
    b = np.zeros((6, 7, 3), np.uint8)
    h = hstack([a, b], gap=2)
    assert h.shape == (10, 13, 3)
    assert (h[:, 4:6] == 255).all() and (h[6:, 6:] == 255).all() and (h[:6, 6:] == 0).all()
    v = vstack([a, b], gap=3)
    assert v.shape == (19, 7, 3)
    assert (v[10:13] == 255).all() and (v[:10, 4:] == 255).all() and (v[13:] == 0).all()
    with pytest.raises(ValueError):
        hstack([])
    with pytest.raises(ValueError):
        vstack([a], gap=-1)
    with pytest.raises(ValueError):
        hstack([a.astype(np.float32)])


def test_save_png_round_trips_rgb_atomically(tmp_path):
    img = np.full((20, 30, 3), 255, np.uint8)
    img[2, 3] = (255, 0, 0)  # pure red in RGB
    path = tmp_path / "fig.png"
    path.write_bytes(b"old")
    save_png(path, img)
    back = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert back.shape == img.shape
    assert back[2, 3].tolist() == [0, 0, 255]  # BGR on disk, i.e. red
    assert np.array_equal(cv2.cvtColor(back, cv2.COLOR_BGR2RGB), img)
    assert [p.name for p in tmp_path.iterdir()] == ["fig.png"]  # no temp file left
    with pytest.raises(ValueError):
        save_png(tmp_path / "bad.png", img[..., 0])
    assert [p.name for p in tmp_path.iterdir()] == ["fig.png"]
