"""Checkpoints: atomic save, exact reload, one-line errors for corrupt files and variant mismatches."""

import pytest
import torch

from kgn_bench.model.checkpoint import FORMAT, CheckpointError, checkpoint_format, load_checkpoint, load_model
from kgn_bench.model.variants import get_variant


def test_round_trip_gives_the_same_outputs(tmp_path, small_model):
    net = small_model(tmp_path / "w.pt", epoch=3)
    loaded = load_model(tmp_path / "w.pt")
    x = torch.randn(1, 4, 64, 64)
    net.eval()
    with torch.no_grad():
        a, b = net(x), loaded.net(x)
    assert a.keys() == b.keys() == {"hm", "reg", "kpts", "width", "scale"}
    for k in a:
        torch.testing.assert_close(a[k], b[k])
    assert loaded.variant.name == "kgnv2" and loaded.meta["epoch"] == 3
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary file left behind


def test_kgn_depth_loads_kgn_weights_and_refuses_others(tmp_path, small_model):
    small_model(tmp_path / "kgn.pt", variant="kgn")
    assert load_model(tmp_path / "kgn.pt", get_variant("kgn_depth")).variant.name == "kgn_depth"
    with pytest.raises(CheckpointError, match="holds 'kgn' weights, but 'kgnv2' needs 'kgnv2' weights"):
        load_model(tmp_path / "kgn.pt", get_variant("kgnv2"))


def test_scale_anchor_travels_with_the_checkpoint(tmp_path, small_model):
    """The anchor is a property of the trained weights: the loaded variant carries it, whichever variant the
    caller asks for, and checkpoints without the entry load as the paper's absolute scale."""
    small_model(tmp_path / "anchored.pt", scale_anchor="depth")
    small_model(tmp_path / "old.pt")
    assert load_model(tmp_path / "anchored.pt").variant.scale_anchor == "depth"
    assert load_model(tmp_path / "anchored.pt", get_variant("kgnv2")).variant.scale_anchor == "depth"
    assert load_model(tmp_path / "old.pt").variant.scale_anchor == "none"
    data = torch.load(tmp_path / "old.pt", weights_only=False)
    del data["scale_anchor"]
    torch.save(data, tmp_path / "older.pt")
    assert load_model(tmp_path / "older.pt").variant == get_variant("kgnv2")
    small_model(tmp_path / "bad.pt", scale_anchor="sonar")
    with pytest.raises(CheckpointError, match="unknown scale_anchor 'sonar'"):
        load_model(tmp_path / "bad.pt")


@pytest.mark.parametrize("content, message", [
    (b"", "not a readable checkpoint"),
    (b"\x00garbage" * 10, "not a readable checkpoint"),
])
def test_corrupt_files_give_one_line(tmp_path, content, message):
    p = tmp_path / "bad.pt"
    p.write_bytes(content)
    with pytest.raises(CheckpointError, match=message) as e:
        load_model(p)
    assert "\n" not in str(e.value)


def test_truncated_and_foreign_files(tmp_path, small_model):
    small_model(tmp_path / "w.pt")
    data = (tmp_path / "w.pt").read_bytes()
    (tmp_path / "cut.pt").write_bytes(data[: len(data) // 2])
    with pytest.raises(CheckpointError, match="not a readable checkpoint"):
        load_checkpoint(tmp_path / "cut.pt")
    torch.save({"state_dict": {}}, tmp_path / "foreign.pt")
    with pytest.raises(CheckpointError, match="not a kgn-bench checkpoint"):
        load_checkpoint(tmp_path / "foreign.pt")
    with pytest.raises(CheckpointError, match="no checkpoint at"):
        load_checkpoint(tmp_path / "missing.pt")


class _RunsCode:
    """Pickled as a call of ``print``: a file that would run code when loaded without ``weights_only``."""

    def __reduce__(self):
        return (print, ("this ran on load",))


def test_checkpoint_format_reads_data_only(tmp_path, small_model, capsys):
    small_model(tmp_path / "w.pt")
    assert checkpoint_format(tmp_path / "w.pt") == FORMAT
    torch.save({"format": "kgn-bench-vgn", "weights": _RunsCode()}, tmp_path / "hostile.pt")
    (tmp_path / "junk.pt").write_bytes(b"\x00junk")
    torch.save([1, 2], tmp_path / "list.pt")
    for name in ("hostile.pt", "junk.pt", "list.pt", "missing.pt"):
        assert checkpoint_format(tmp_path / name) is None, name
    assert "this ran on load" not in capsys.readouterr().out


def test_weights_that_do_not_fit_the_network(tmp_path, small_model):
    small_model(tmp_path / "w.pt", variant="kgn", label="kgnv2")  # no scale head, labelled kgnv2
    with pytest.raises(CheckpointError, match="weights do not fit the network"):
        load_model(tmp_path / "w.pt")


def test_weights_are_checked_against_their_model_card(tmp_path, small_model):
    from kgn_bench.model.checkpoint import card_sha256, export_weights

    small_model(tmp_path / "final.pt", epoch=1, history=[])
    weights, card = export_weights(tmp_path / "final.pt", "mine", tmp_path / "w")
    assert card_sha256(weights) is not None and len(card_sha256(weights)) == 64
    load_checkpoint(weights)
    data = bytearray(weights.read_bytes())
    start = len(data) // 2
    data[start : start + 4096] = bytes(b ^ 0xFF for b in data[start : start + 4096])  # same size, 4 KB flipped
    weights.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match=r"SHA-256 differs from its model card mine\.md"):
        load_checkpoint(weights)
    card.unlink()  # without a card (a training run's checkpoint) there is no hash to check
    try:
        load_model(weights)
    except CheckpointError as e:
        assert "SHA-256" not in str(e)


def test_every_shipped_weights_file_matches_its_card():
    from kgn_bench.model.checkpoint import card_sha256, file_sha256
    from kgn_bench.resources import weights_dir

    shipped = sorted(weights_dir().glob("*.pt"))
    assert shipped
    for w in shipped:
        assert card_sha256(w) == file_sha256(w), w.name
