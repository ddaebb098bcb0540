"""kgn-bench eval (kgn_bench.cli.evaluation), with ship: shipped weights evaluated and drawn, the weights'
own decoding variant by default, a variant the weights cannot serve refused in one line."""

from kgn_bench.cli import main

HISTORY = [{"epoch": 1, "total": 3.5, "hm": 1.0, "seconds": 60.0,
            "eval": {"1 cm / 20°": {"gsr": 0.25, "gcr": None, "osr": 0.5}}, "eval_views": 2}]


def test_export_eval_and_show_commands(tiny_dataset, tmp_path, capsys, small_model):
    import json

    from kgn_bench.model.checkpoint import load_checkpoint

    root, _ = tiny_dataset
    small_model(tmp_path / "final.pt", optimizer={"state": {}}, epoch=1, history=HISTORY, git_commit="abc1234",
                train={"name": "train_x", "train": {"batch_size": 8}})
    assert main(["ship", str(tmp_path / "final.pt"), "--name", "mine", "--out", str(tmp_path / "w")]) == 0
    shipped = load_checkpoint(tmp_path / "w" / "mine.pt")
    assert "optimizer" not in shipped and shipped["epoch"] == 1
    card = (tmp_path / "w" / "mine.md").read_text()
    assert "| variant | `kgnv2`, scale head: absolute distance |" in card and "abc1234" in card
    assert "GSR 25.0 % GCR n/a OSR 50.0 %" in card

    weights = str(tmp_path / "w" / "mine.pt")
    assert main(["eval", "vision", "--weights", weights, "--data", str(root), "--views", "2",
                 "--out", str(tmp_path / "ev"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "ev" / "vision.json").read_text())
    assert summary["images"] == 2 and summary["variant"] == "kgnv2" and len(summary["thresholds"]) == 3
    assert (tmp_path / "ev" / "vision.md").read_text().startswith("Vision metrics over 2 images")

    assert main(["eval", "show", "--weights", weights, "--data", str(root), "--scene", "0",
                 "--out", str(tmp_path / "pred.png")]) == 0
    import cv2

    img = cv2.imread(str(tmp_path / "pred.png"))
    assert img.shape == (480, 1280, 3)

    # the wrong decoding variant for these weights: one line, exit 2
    capsys.readouterr()
    assert main(["eval", "vision", "--weights", weights, "--variant", "kgn", "--data", str(root)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds 'kgnv2' weights" in err


def test_eval_vision_decodes_with_the_weights_own_variant(tiny_dataset, tmp_path, capsys):
    import json

    root, _ = tiny_dataset
    assert main(["eval", "vision", "--weights", "kgn", "--data", str(root), "--views", "1", "--out",
                 str(tmp_path / "e"), "--quiet"]) == 0
    assert json.loads((tmp_path / "e" / "vision.json").read_text())["variant"] == "kgn"
    assert main(["eval", "vision", "--weights", "kgn", "--variant", "kgn_depth", "--data", str(root), "--views",
                 "1", "--quiet"]) == 0  # kgn weights serve kgn_depth
    capsys.readouterr()
    assert main(["eval", "vision", "--weights", "kgn", "--variant", "kgnv2", "--data", str(root), "--quiet"]) == 2
    assert "holds 'kgn' weights, but 'kgnv2' needs 'kgnv2' weights" in capsys.readouterr().err
