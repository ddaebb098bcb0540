"""matplotlib figures: real PNGs of the expected size, Unicode labels, gaps for missing cells."""

import cv2
import numpy as np
import pytest

from kgn_bench.viz.figures import (
    DPI,
    Line,
    Panel,
    bar_chart,
    line_panels,
    save_figure,
    save_training_curves,
    training_figure,
    vgn_training_figure,
)


def _read(path):
    img = cv2.imread(str(path))
    assert img is not None
    return img


def test_bar_chart_with_whiskers_and_a_gap(tmp_path):
    values = np.array([[96.7, 99.2], [np.nan, 95.0]])
    fig = bar_chart(["single, primitives", "σ-clutter · clear"], ["kgnv2", "antipodal"], values, values - 3,
                    np.minimum(values + 2, 100), title="success with Wilson 95 % intervals", ylabel="rate (%)")
    ax = fig.axes[0]
    assert len(ax.patches) == 3  # the NaN cell leaves a gap
    assert [t.get_text() for t in ax.get_xticklabels()] == ["single, primitives", "σ-clutter · clear"]
    save_figure(fig, tmp_path / "b.png")
    h, w = _read(tmp_path / "b.png").shape[:2]
    assert (w, h) == (round(fig.get_figwidth() * DPI), round(fig.get_figheight() * DPI))
    assert [p.name for p in tmp_path.iterdir()] == ["b.png"]  # written atomically, nothing left over
    with pytest.raises(ValueError, match="must be"):
        bar_chart(["a"], ["x", "y"], np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2)), title="", ylabel="")


def test_bar_chart_rows_give_slots_only_to_series_present(tmp_path):
    groups = [f"task {i}" for i in range(10)]
    values = np.full((10, 3), 50.0)
    values[:7, 2] = np.nan  # a detector that runs the last three tasks only
    fig = bar_chart(groups, ["a", "b", "vgn"], values, values - 5, values + 5, title="t", ylabel="%", per_row=4)
    axes = fig.axes
    assert len(axes) == 3  # ceil(10 / 4) rows of at most ceil(10 / 3) = 4 groups
    assert [[t.get_text() for t in ax.get_xticklabels()] for ax in axes] == [groups[:4], groups[4:8], groups[8:]]
    assert [len(ax.patches) for ax in axes] == [8, 8 + 1, 6]  # 'vgn' has a slot only where it has a value
    widths = [{round(p.get_width(), 6) for p in ax.patches} for ax in axes]
    assert widths[0] == {round(0.4 * 0.92, 6)} and widths[2] == {round(0.8 / 3 * 0.92, 6)}
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["a", "b", "vgn"]
    assert fig.legends[0].get_title().get_text() == "t"
    save_figure(fig, tmp_path / "rows.png")
    assert _read(tmp_path / "rows.png").shape[0] > 3 * 300  # three rows of axes


def test_line_panels_log_scale(tmp_path):
    panels = [Panel("rotation", "d (m)", "error (°)", [Line("σ = 2 px", [0.3, 1.0], [0.5, 2.0], dashed=True)],
                    log_y=True), Panel("translation", "d (m)", "cm", [Line("a", [0, 1], [1, 2], color=3)])]
    fig = line_panels(panels)
    assert [a.get_yscale() for a in fig.axes] == ["log", "linear"]
    assert fig.axes[0].lines[0].get_linestyle() == "--"
    save_figure(fig, tmp_path / "l.png")
    assert _read(tmp_path / "l.png").std() > 5  # not blank


def test_training_figure_plots_losses_and_held_out_metrics():
    history = [{"epoch": e, "total": 4.0 / e, "hm": 2.0 / e} for e in range(1, 4)]
    history[2]["eval"] = {"1 cm / 20°": {"gsr": 0.4, "gcr": 0.2, "osr": 0.7}}
    history[2]["eval_views"] = 50
    fig = training_figure(history, "kgnv2")
    left, right = fig.axes
    assert [line.get_label() for line in left.lines] == ["total", "hm"]
    assert len(right.lines) == 3 and right.lines[0].get_ydata()[0] == pytest.approx(40.0)


def test_training_curves_of_shipped_weights(tmp_path, small_model):
    """``kgn-bench ship``'s curves: the PNG beside the weights is ``training_figure`` of their history, titled
    with the weights' name and the training config; weights without history get none."""
    from kgn_bench.model.checkpoint import export_weights

    history = [{"epoch": 1, "total": 2.0, "hm": 1.0, "eval": {"1 cm / 20°": {"gsr": 0.4, "gcr": 0.2, "osr": 0.7}},
                "eval_views": 4}, {"epoch": 2, "total": 1.0, "hm": 0.5}]
    small_model(tmp_path / "final.pt", epoch=2, history=history, train={"name": "train_tiny"})
    weights, _ = export_weights(tmp_path / "final.pt", "mine", tmp_path / "w")
    assert not (tmp_path / "w" / "mine_training.png").exists()  # the model layer draws nothing
    png = save_training_curves(weights)
    assert png == tmp_path / "w" / "mine_training.png"
    save_figure(training_figure(history, "mine: train_tiny"), tmp_path / "expected.png")
    assert png.read_bytes() == (tmp_path / "expected.png").read_bytes()
    small_model(tmp_path / "bare.pt", epoch=0, history=[])
    bare, _ = export_weights(tmp_path / "bare.pt", "bare", tmp_path / "w")
    assert save_training_curves(bare) is None and not (tmp_path / "w" / "bare_training.png").exists()


def test_vgn_training_figure_plots_losses_and_held_out_rates():
    history = [{"epoch": e, "loss": 1.0 / e, "bce": 0.6 / e, "rotation": 0.3 / e, "width": 0.1 / e,
                "held_out_loss": 1.2 / e, "accuracy": 0.5 + 0.1 * e, "precision": 0.4, "recall": None,
                "rotation_hit": 0.2} for e in range(1, 4)]
    fig = vgn_training_figure(history, "vgn: 300 scenes")
    left, right = fig.axes
    assert [line.get_label() for line in left.lines] == ["loss", "bce", "rotation", "width", "held-out loss"]
    assert [line.get_label() for line in right.lines] == ["accuracy", "precision", "rotation hit"]
    assert list(right.lines[0].get_ydata()) == pytest.approx([60.0, 70.0, 80.0])


def test_training_curves_of_shipped_vgn_weights(tmp_path):
    """``kgn-bench ship`` on a VGN run: the PNG beside the weights is ``vgn_training_figure`` of their history,
    titled with the weights' name and the number of scenes, and the card links it."""
    from kgn_bench.model.vgn_checkpoint import export_vgn_weights, save_vgn_checkpoint, vgn_payload
    from kgn_bench.model.vgn_network import VGNNet
    from kgn_bench.tsdf import VoxelGrid

    history = [{"epoch": 1, "loss": 0.9, "held_out_loss": 0.8, "accuracy": 0.6, "precision": 0.5, "recall": 0.7}]
    save_vgn_checkpoint(tmp_path / "final.pt", {**vgn_payload(VGNNet(), VoxelGrid(0.3, 40, 4.0)), "epoch": 1,
                                                 "history": history, "dataset": {"scenes": 300}})
    weights, card = export_vgn_weights(tmp_path / "final.pt", "vgn", tmp_path / "w")
    png = save_training_curves(weights)
    assert png == tmp_path / "w" / "vgn_training.png" and "![training curves](vgn_training.png)" in card.read_text()
    save_figure(vgn_training_figure(history, "vgn: 300 scenes"), tmp_path / "expected.png")
    assert png.read_bytes() == (tmp_path / "expected.png").read_bytes()
