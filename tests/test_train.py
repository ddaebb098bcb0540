"""Training: config validation, a tiny real run on a generated dataset, resume, refusal of a changed config."""

import json

import pytest
import torch

from kgn_bench.environment import cpu_model
from kgn_bench.eval.vision import held_out_evaluator
from kgn_bench.model.checkpoint import CheckpointError, load_checkpoint, load_model
from kgn_bench.training.train import (
    TrainConfigError,
    autocast_dtype,
    bfloat16_emulated,
    load_train_config,
    machine_label,
    train,
)

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
    ("[train]\nprecision = 'fp8'\n", "unknown \\[train\\] precision 'fp8'"),
    ("[network]\noutput_stride = 8\n", "output_stride must be one of"),
    ("[train]\nheatmap_radius = 0\n", "heatmap_radius must be 1 to 4"),
    ("[train]\nextra_data = [3]\n", "extra_data must be a list of strings"),
    ("[train]\ninit = 3\n", "init must be str"),
])
def test_bad_configs_give_one_line(tmp_path, text, message):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(TrainConfigError, match=message) as e:
        load_train_config(p)
    assert "\n" not in str(e.value)


def test_autocast_follows_the_precision_the_device_and_the_kernels(monkeypatch):
    cpu, cuda = torch.device("cpu"), torch.device("cuda")
    bf16, plain = frozenset({"avx2", "avx512_bf16"}), frozenset({"avx2"})
    assert autocast_dtype(cpu, "float32", bf16) is None and autocast_dtype(cuda, "float32") is None
    assert autocast_dtype(cpu, "bfloat16", plain) is torch.bfloat16 and autocast_dtype(cuda, "auto") is torch.bfloat16
    monkeypatch.setenv("KGN_BENCH_KERNELS", "portable")
    assert autocast_dtype(cpu, "auto", bf16) is None  # oneDNN capped at AVX2 emulates bfloat16
    monkeypatch.setenv("KGN_BENCH_KERNELS", "native")
    assert autocast_dtype(cpu, "auto", bf16) is torch.bfloat16
    assert autocast_dtype(cpu, "auto", plain) is None
    with pytest.raises(ValueError, match="precision"):
        autocast_dtype(cpu, "half")


def test_a_forced_bfloat16_is_named_where_the_cpu_would_emulate_it(monkeypatch):
    cpu, cuda = torch.device("cpu"), torch.device("cuda")
    bf16, plain = frozenset({"avx2", "avx512_bf16"}), frozenset({"avx2"})
    monkeypatch.setenv("KGN_BENCH_KERNELS", "native")
    assert bfloat16_emulated(cpu, "bfloat16", plain) and not bfloat16_emulated(cpu, "bfloat16", bf16)
    assert not bfloat16_emulated(cpu, "auto", plain) and not bfloat16_emulated(cuda, "bfloat16", plain)
    monkeypatch.setenv("KGN_BENCH_KERNELS", "portable")
    assert bfloat16_emulated(cpu, "bfloat16", bf16)


def test_stride_two_bfloat16_run_trains_and_loads_as_a_stride_two_detector(tmp_path, tiny_dataset):
    """A stride-2 network trained with bfloat16 autocast: finite losses, the card's precision, and a detector
    whose maps are twice as fine as the stride-4 network's."""
    root, _ = tiny_dataset
    p = _config(tmp_path, root)
    p.write_text(p.read_text().replace("lr_steps = [1]", "lr_steps = [1]\nprecision = 'bfloat16'")
                 .replace("head_conv = 16", "head_conv = 16\noutput_stride = 2"))
    final = train(load_train_config(p), progress=False)
    ckpt = load_checkpoint(final)
    assert ckpt["precision"] == "bfloat16" and ckpt["network"]["output_stride"] == 2
    assert all(torch.isfinite(torch.tensor(v)) for k, v in ckpt["history"][0].items() if k in ("total", "hm"))
    model = load_model(final)
    assert model.network.output_stride == 2
    from kgn_bench.data.format import read_view, scene_dir
    from kgn_bench.model.preprocess import prepare

    rgbd = read_view(scene_dir(root, 0), 0)
    x, _, (ho, wo) = prepare(rgbd.rgb, rgbd.depth, model.input_config, 2)
    with torch.no_grad():
        out = model.net(x[None])
    h, w = rgbd.depth.shape
    assert out["hm"].shape[2:] == (x.shape[1] // 2, x.shape[2] // 2) and (ho, wo) == (-(-h // 4), -(-w // 4))


def test_a_run_from_before_a_new_setting_resumes(tmp_path, tiny_dataset):
    """A checkpoint written before ``precision``, ``channels_last`` and ``output_stride`` existed resumes at their
    defaults."""
    root, _ = tiny_dataset
    cfg = load_train_config(_config(tmp_path, root, epochs=1))
    train(cfg, progress=False)
    last = tmp_path / "run" / "last.pt"
    ckpt = load_checkpoint(last)
    del ckpt["train"]["train"]["precision"], ckpt["train"]["network"]["output_stride"]
    del ckpt["train"]["train"]["channels_last"], ckpt["train"]["train"]["heatmap_radius"]
    torch.save(ckpt, last)
    train(cfg, progress=False)  # accepted: nothing left to train
    assert load_checkpoint(tmp_path / "run" / "final.pt")["epoch"] == 1
    ckpt["train"]["train"]["lr"] = 0.5
    torch.save(ckpt, last)
    with pytest.raises(CheckpointError, match="different config"):
        train(cfg, progress=False)


def test_a_channels_last_run_trains_the_same_network(tmp_path, tiny_dataset):
    """The layout changes the kernels, not the network: the first epoch's losses agree with the contiguous
    run's to float32 rounding, and the weights load into a network in the default layout."""
    root, _ = tiny_dataset
    finals = {}
    for channels_last in (False, True):
        folder = tmp_path / str(channels_last)
        folder.mkdir()
        cfg = load_train_config(_config(folder, root), [("train.channels_last", str(channels_last).lower())])
        assert cfg.train.channels_last is channels_last
        finals[channels_last] = train(cfg, progress=False)
    plain, last = (load_checkpoint(finals[k])["history"][0] for k in (False, True))
    assert plain["total"] == pytest.approx(last["total"], rel=1e-4)
    model = load_model(finals[True])
    assert not model.net.channels_last and model.net.heads["hm"][0].weight.is_contiguous()


def test_shipped_configs_load():
    from pathlib import Path

    for p in sorted(Path(__file__).parents[1].glob("tasks/train_*.toml")):
        cfg = load_train_config(p)
        assert cfg.train.variant in ("kgn", "kgnv2", "kgnv2_sbranch")


def test_settings_override_the_file_and_are_validated_like_it(tmp_path, tiny_dataset):
    root, _ = tiny_dataset
    p = _config(tmp_path, root)
    cfg = load_train_config(p, [("train.epochs", "3"), ("network.output_stride", "2"), ("train.lr_steps", "[2]"),
                                ("train.assignment", "frontal")])
    assert (cfg.train.epochs, cfg.network.output_stride, cfg.train.lr_steps, cfg.train.assignment) == (
        3, 2, (2,), "frontal")
    with pytest.raises(TrainConfigError, match="output_stride must be one of"):
        load_train_config(p, [("network.output_stride", "3")])
    with pytest.raises(TrainConfigError, match="unknown key 'speed'"):
        load_train_config(p, [("train.speed", "3")])
    with pytest.raises(TrainConfigError, match=r"must be section\.name"):
        load_train_config(p, [("epochs", "3")])


def test_a_dataset_of_test_objects_is_never_trained_on(tmp_path, tiny_dataset):
    import shutil

    from kgn_bench.data.format import DatasetError

    root, _ = tiny_dataset
    leaky = tmp_path / "leaky"
    shutil.copytree(root, leaky)
    manifest = json.loads((leaky / "dataset.json").read_text())
    manifest["object_types"] = ["cuboid", "pb_000"]
    (leaky / "dataset.json").write_text(json.dumps(manifest))
    with pytest.raises(DatasetError, match=r"real test objects \(pb_000\)"):
        train(load_train_config(_config(tmp_path, leaky)), progress=False)
    assert not (tmp_path / "run" / "last.pt").exists()


def test_a_fine_tune_starts_from_init_and_its_card_says_so(tmp_path, tiny_dataset):
    """``[train] init`` loads the checkpoint's weights before the first step (an epoch at a tiny rate leaves
    them unchanged, where another seed's random weights would differ wholesale); the checkpoint and the model
    card name it; a checkpoint of another variant is refused before anything is written."""
    from kgn_bench.model.checkpoint import export_weights

    root, _ = tiny_dataset
    base = train(load_train_config(_config(tmp_path, root)), progress=False)
    p = tmp_path / "fine.toml"
    text = TINY.format(variant="kgnv2", data=root, out=tmp_path / "fine", epochs=1)
    p.write_text(text.replace("lr = 1e-3", f'lr = 1e-9\ninit = "{base}"\nseed = 5'))
    fine = train(load_train_config(p), progress=False)
    a, b = load_checkpoint(base)["model"], load_checkpoint(fine)["model"]
    weights = [k for k in a if a[k].is_floating_point() and "running_" not in k]  # batch-norm statistics move
    assert max((a[k] - b[k]).abs().max().item() for k in weights) < 1e-6
    init = load_checkpoint(fine)["init"]
    assert init["path"] == str(base) and init["epochs"] == 1 and len(init["sha256"]) == 64
    _, card = export_weights(fine, "fine", tmp_path / "shipped")
    assert f"| initialised from | `{base}`" in card.read_text()
    # the init file replaced by other weights: the run no longer resumes from it
    q = tmp_path / "other.toml"
    q.write_text(TINY.format(variant="kgnv2", data=root, out=tmp_path / "other", epochs=1).replace("lr = 1e-3",
                                                                                                 "lr = 1e-3\nseed = 9"))
    other = train(load_train_config(q), progress=False)
    base.write_bytes(other.read_bytes())
    with pytest.raises(CheckpointError, match="started from other weights"):
        train(load_train_config(p), progress=False)
    # kgnv2 weights cannot start a kgn run, and the refusal comes before the run folder exists
    q = tmp_path / "wrong.toml"
    q.write_text(TINY.format(variant="kgn", data=root, out=tmp_path / "wrong", epochs=1)
                 .replace("lr = 1e-3", f'lr = 1e-3\ninit = "{base}"'))
    with pytest.raises(CheckpointError, match="holds 'kgnv2' weights"):
        train(load_train_config(q), progress=False)
    assert not (tmp_path / "wrong" / "last.pt").exists()


def test_extra_data_joins_the_training_split_and_the_identity(tmp_path, tiny_dataset):
    """``[train] extra_data``: the training views of both datasets make one epoch (twice the batches of one
    dataset), the checkpoint keeps both identities, and a resume with another extra dataset is refused."""
    import shutil

    root, _ = tiny_dataset
    other = tmp_path / "other"
    shutil.copytree(root, other)
    manifest = json.loads((other / "dataset.json").read_text())
    manifest["note"] = "a copy"
    (other / "dataset.json").write_text(json.dumps(manifest))
    p = tmp_path / "mix.toml"
    p.write_text(TINY.format(variant="kgnv2", data=root, out=tmp_path / "run", epochs=1)
                 .replace("lr = 1e-3", f'lr = 1e-3\nextra_data = ["{other}"]'))
    cfg = load_train_config(p)
    from kgn_bench.training.train import _start_run

    (tmp_path / "x").mkdir()
    single = _start_run(load_train_config(_config(tmp_path / "x", root)), None, None)
    mixed = _start_run(cfg, None, None)
    assert len(mixed.dataset) == 2 * len(single.dataset)
    train(cfg, progress=False)
    ckpt = load_checkpoint(tmp_path / "run" / "last.pt")
    assert [e["path"] for e in ckpt["dataset"]["extra"]] == [str(other)]
    assert ckpt["dataset"]["sha256"] != single.identity["sha256"]
