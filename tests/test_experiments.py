"""The Table I / II builders: model registry ↔ training configs, the evaluation cache, the tables' numbers."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from kgn_bench.eval import experiments as ex
from kgn_bench.eval.experiments import (
    DATASETS,
    MODELS,
    PAPER_TABLE1,
    ExperimentError,
    build_table1,
    build_table2,
    evaluate_cached,
)
from kgn_bench.model.variants import get_variant
from kgn_bench.training.train import load_train_config

ROOT = Path(__file__).parents[1]


def _summary(rates: list[tuple[float, float, float]]) -> dict:
    """An eval-vision summary with the given (GSR, GCR, OSR) fractions per threshold."""
    labels = ("1 cm / 20°", "2 cm / 30°", "3 cm / 45°")
    return {"thresholds": [{"label": lab, "gsr": g, "gcr": c, "osr": o} for lab, (g, c, o) in zip(labels, rates)]}


@pytest.fixture
def fake_setup(tmp_path, monkeypatch, tiny_dataset):
    """Weights files for every model in a temporary weights folder and both test splits pointing at the
    tiny dataset; returns (data_dirs, weights folder)."""
    weights = tmp_path / "weights"
    weights.mkdir()
    for m in MODELS.values():
        (weights / f"{m.weights}.pt").write_bytes(m.weights.encode())
    monkeypatch.setattr(ex, "WEIGHTS_DIR", weights)
    root, _ = tiny_dataset
    return {"single": root, "multi": root}, weights


def test_every_model_has_a_training_config_that_produces_its_weights():
    for m in MODELS.values():
        cfg = load_train_config(ROOT / m.config)
        assert cfg.train.variant == get_variant(m.variant).weights_variant
        assert Path(cfg.train.data) == Path(DATASETS[m.trained_on].path)
        assert f"{cfg.train.out}/final.pt" in m.commands and f"--name {m.weights}" in m.commands


def test_cache_is_reused_until_the_weights_or_the_labels_change(fake_setup, tmp_path, monkeypatch):
    data_dirs, weights = fake_setup
    calls = []

    def evaluator(model, w, data, views):
        calls.append(model.name)
        return _summary([(0.5, 0.4, 0.9)] * 3)

    model = MODELS["kgnv2_multi"]
    first = evaluate_cached(model, "multi", data_dirs, tmp_path / "cache", evaluator=evaluator)
    again = evaluate_cached(model, "multi", data_dirs, tmp_path / "cache", evaluator=evaluator)
    assert calls == ["kgnv2_multi"] and again == first
    evaluate_cached(model, "multi", data_dirs, tmp_path / "cache", views=3, evaluator=evaluator)
    (weights / "kgnv2.pt").write_bytes(b"retrained")
    evaluate_cached(model, "multi", data_dirs, tmp_path / "cache", views=3, evaluator=evaluator)
    assert calls == ["kgnv2_multi"] * 3
    stored = json.loads((tmp_path / "cache" / "kgnv2_multi_on_multi.json").read_text())
    assert stored["key"]["views"] == 3 and stored["model"] == "kgnv2_multi"
    # a change to the collision labelling (the ground truth is relabelled at evaluation) invalidates the cache
    monkeypatch.setattr(ex, "LABEL_VERSION", ex.LABEL_VERSION + 1)
    evaluate_cached(model, "multi", data_dirs, tmp_path / "cache", views=3, evaluator=evaluator)
    assert calls == ["kgnv2_multi"] * 4


def test_missing_weights_name_the_commands_that_make_them(fake_setup, tmp_path):
    data_dirs, weights = fake_setup
    (weights / "kgn_single.pt").unlink()
    with pytest.raises(ExperimentError, match=r"kgn-bench train tasks/train_kgn_single.toml .* --name kgn_single"):
        build_table1(data_dirs, tmp_path, evaluator=lambda *a: _summary([(0.5, 0.5, 0.5)] * 3))
    text, payload = build_table1(data_dirs, tmp_path, partial=True,
                                 evaluator=lambda *a: _summary([(0.5, 0.5, 0.5)] * 3))
    assert "kgn_single" not in payload["ours"] and len(payload["missing"]) == 1
    assert "| KGN (single) | ours | — | — | — |" in text


def test_table1_prints_ours_the_paper_and_the_difference_and_flags_losses(fake_setup, tmp_path):
    data_dirs, _ = fake_setup

    def evaluator(model, w, data, views):
        if model.name == "kgnv2_multi":  # behind KGN (multi) on GCR at the first threshold
            return _summary([(0.9, 0.1, 0.95), (0.95, 0.9, 0.97), (0.97, 0.95, 0.99)])
        return _summary([(0.5, 0.4, 0.8)] * 3)

    text, payload = build_table1(data_dirs, tmp_path, evaluator=evaluator)
    assert payload["ours"]["kgnv2_multi"]["multi"][0] == pytest.approx((90.0, 10.0, 95.0))
    p = PAPER_TABLE1["kgnv2_multi"]["multi"][0]
    assert f"| | paper | {p[0]:.1f} / {p[1]:.1f} / {p[2]:.1f}" in text
    assert f"| | Δ | {90.0 - p[0]:+.1f} / {10.0 - p[1]:+.1f} / {95.0 - p[2]:+.1f}" in text
    losses = payload["kgnv2_behind_kgn"]["multi"]
    assert len(losses) == 2 and all("1 cm / 20°, GCR: 10.0 < 40.0" in s for s in losses)
    assert payload["kgnv2_behind_kgn"]["single"] == []
    assert (tmp_path / "vision_table1.md").read_text() == text


def test_table2_averages_the_three_thresholds(fake_setup, tmp_path):
    data_dirs, _ = fake_setup
    text, payload = build_table2(data_dirs, tmp_path,
                                 evaluator=lambda *a: _summary([(0.1, 0.2, 0.3), (0.2, 0.4, 0.6), (0.3, 0.6, 0.9)]))
    assert payload["ours"]["kgnv2_single"] == pytest.approx((20.0, 40.0, 60.0))
    assert "| 20.0 / 40.0 / 60.0 | 39.7 / 31.1 / 56.7 | -19.7 / +8.9 / +3.3 |" in text
    assert "not in paper" in text  # kgn_depth is our addition


def test_real_evaluation_of_a_small_model(tiny_dataset, small_model, tmp_path, monkeypatch):
    weights = tmp_path / "weights"
    small_model(weights / "kgnv2.pt", variant="kgnv2")
    monkeypatch.setattr(ex, "WEIGHTS_DIR", weights)
    root, _ = tiny_dataset
    summary = evaluate_cached(MODELS["kgnv2_multi"], "multi", {"multi": root}, tmp_path / "cache", views=2)
    assert summary["images"] == 2 and len(summary["thresholds"]) == 3
    assert (tmp_path / "cache" / "kgnv2_multi_on_multi.md").read_text().startswith("# KGNv2 (multi)")


@pytest.mark.parametrize(("weights", "recipe"), [("kgnv2", "recipe 3 (16 epochs, frontal targets, depth-anchored"),
                                                 ("kgnv2_recipe2", "recipe 2 (12 epochs"),
                                                 ("kgn", "recipe 3 (16 epochs, frontal targets)"),
                                                 ("kgn_recipe1", "recipe 1 (12 epochs)")])
def test_the_tables_name_the_recipe_of_the_shipped_weights(weights, recipe):
    """The recipe is read from the checkpoint itself, so a table row says how its weights were trained."""
    assert ex.recipe_of(ex.ModelSpec("m", "kgnv2", weights, "multi", "M")).startswith(recipe)
    assert ex.recipe_of(ex.ModelSpec("m", "kgnv2", "no_such_weights", "multi", "M")) == "not trained"


@pytest.mark.parametrize(("epochs", "recipe"), [(32, "recipe 4 (32 epochs"), (20, "recipe 3 (20 epochs"),
                                                (12, "recipe 2 (12 epochs")])
def test_a_recipe_4_checkpoint_is_named_recipe_4(tmp_path, monkeypatch, epochs, recipe):
    """The shipped kgnv2 checkpoint re-saved as if it had trained ``epochs`` epochs is named by its length."""
    import torch

    data = torch.load(ROOT / "assets" / "weights" / "kgnv2.pt", map_location="cpu", weights_only=False)
    data["epoch"] = epochs
    torch.save(data, tmp_path / "long.pt")
    monkeypatch.setattr(ex, "WEIGHTS_DIR", tmp_path)
    assert ex.recipe_of(ex.ModelSpec("m", "kgnv2", "long", "multi", "M")).startswith(recipe)


def test_every_models_config_is_the_one_its_shipped_weights_were_trained_with():
    """The registry's config reproduces the shipped weights: the checkpoint's recorded [train] settings (run
    folder, schedule, seed, target assignment) are the config's. A model shipped from another config without
    updating ``ModelSpec.config_stem`` fails here."""
    from kgn_bench.model.checkpoint import load_checkpoint

    keys = ("out", "epochs", "lr", "lr_steps", "batch_size", "seed", "assignment")
    for m in MODELS.values():
        recorded = load_checkpoint(ROOT / "assets" / "weights" / f"{m.weights}.pt")["train"]["train"]
        cfg = load_train_config(ROOT / m.config).train
        assert {k: recorded.get(k) for k in keys} == {
            k: (list(v) if isinstance(v, tuple) else v) for k in keys for v in [getattr(cfg, k)]}, m.name
