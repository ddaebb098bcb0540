"""Training: config validation, a tiny real run on a generated dataset, resume, refusal of a changed config."""

import json

import pytest
import torch

from kgn_bench.environment import cpu_model
from kgn_bench.eval.vision import held_out_evaluator
from kgn_bench.model.checkpoint import CheckpointError, load_checkpoint, load_model
from kgn_bench.training.train import TrainConfigError, load_train_config, machine_label, train

TINY = """
[train]
variant = "{variant}"
data = "{data}"
out = "{out}"
epochs = {epochs}
batch_size = 2
lr = 1e-3
lr_steps = [1]
workers = 0
eval_every = 1
eval_views = 1

[network]
stem_channels = 8
stage_channels = [8, 16, 16, 32]
stage_blocks = [1, 1, 1, 1]
neck_channels = 16
head_conv = 16

[augment]
input_size = [64, 64]
"""


def _config(tmp_path, data, epochs=1, variant="kgnv2", name="train_tiny"):
    p = tmp_path / f"{name}.toml"
    p.write_text(TINY.format(variant=variant, data=data, out=tmp_path / "run", epochs=epochs))
    return p


def test_tiny_run_trains_checkpoints_and_resumes(tmp_path, tiny_dataset):
    root, _ = tiny_dataset
    cfg = load_train_config(_config(tmp_path, root))
    final = train(cfg, progress=False, evaluate=held_out_evaluator)
    history = [json.loads(line) for line in (tmp_path / "run" / "history.jsonl").read_text().splitlines()]
    assert [h["epoch"] for h in history] == [1]
    assert history[0]["total"] > 0 and "eval" in history[0]
    ckpt = load_checkpoint(tmp_path / "run" / "last.pt")
    assert ckpt["epoch"] == 1 and "optimizer" in ckpt and ckpt["dataset"]["sha256"]
    assert ckpt["train"]["train"]["variant"] == "kgnv2" and ckpt["git_commit"]
    assert ckpt["machine"] == machine_label(torch.device("cpu")) and (cpu_model() or "unknown CPU") in ckpt["machine"]
    shipped = load_checkpoint(final)
    assert "optimizer" not in shipped
    assert load_model(final).variant.name == "kgnv2"
    # the same command again: nothing left to train, history unchanged
    train(cfg, progress=False, evaluate=held_out_evaluator)
    assert len((tmp_path / "run" / "history.jsonl").read_text().splitlines()) == 1
    # a different config writing to the same folder is refused
    changed = load_train_config(_config(tmp_path, root, epochs=2, name="changed"))
    with pytest.raises(CheckpointError, match="different config"):
        train(changed, progress=False, evaluate=held_out_evaluator)


def test_evaluator_runs_on_schedule_and_leaves_the_weights_alone(tmp_path, tiny_dataset):
    """The held-out evaluator is an argument: called after every ``eval_every``-th epoch with the network in
    eval mode, its figures go into the history; without one no epoch is evaluated and the weights are the same."""
    root, _ = tiny_dataset
    calls = []

    def fake(model, data, views):
        calls.append((model.net.training, model.variant.name, str(data), views))
        return {"thresholds": [{"label": "1cm/20°", "gsr": 0.5, "gcr": 0.25, "osr": None}], "images": views}

    finals = {}
    for name, evaluate in (("with", fake), ("without", None)):
        (tmp_path / name).mkdir()
        cfg = load_train_config(_config(tmp_path / name, root, epochs=2))
        finals[name] = load_checkpoint(train(cfg, progress=False, evaluate=evaluate))
    assert calls == [(False, "kgnv2", str(root), 1)] * 2
    with_eval, without = finals["with"]["history"], finals["without"]["history"]
    assert [h["eval"] for h in with_eval] == [{"1cm/20°": {"gsr": 0.5, "gcr": 0.25, "osr": None}}] * 2
    assert all("eval" not in h and "eval_views" not in h for h in without)
    assert [h["total"] for h in with_eval] == [h["total"] for h in without]
    for k, v in finals["with"]["model"].items():
        assert torch.equal(v, finals["without"]["model"][k]), k


@pytest.mark.parametrize("text, message", [
    ("[train]\nvariant = 'kgnv3'\n", "unknown variant 'kgnv3'"),
    ("[train]\nvariant = 'kgn_depth'\n", "train that one"),
    ("[train]\nepochs = 0\n", "epochs and batch_size must be"),
    ("[train]\nspeed = 3\n", "unknown key"),
    ("[optimiser]\n", "unknown section"),
    ("[augment]\ninput_size = [100, 64]\n", "multiples of 32"),
    ("[train\n", "not valid TOML"),
    ("[train]\nvariant = 'kgn'\nscale_anchor = 'depth'\n", "no scale head to anchor"),
    ("[train]\nscale_anchor = 'sonar'\n", "unknown scale_anchor 'sonar'"),
    ("[train]\nassignment = 'random'\n", "unknown \\[train\\] assignment 'random'"),
])
def test_bad_configs_give_one_line(tmp_path, text, message):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(TrainConfigError, match=message) as e:
        load_train_config(p)
    assert "\n" not in str(e.value)


def test_shipped_configs_load():
    from pathlib import Path

    for p in sorted(Path(__file__).parents[1].glob("tasks/train_*.toml")):
        cfg = load_train_config(p)
        assert cfg.train.variant in ("kgn", "kgnv2", "kgnv2_sbranch")
