"""The command handlers' shared checks (kgn_bench.cli.common): an output that cannot be written is one line
before any work, more workers than cores a warning."""

from kgn_bench.cli import main

TINY = '[task]\nname = "tiny"\nprotocol = "single_object"\ntrials = 1\n[objects]\nset = ["cuboid"]\n'


def _unwritable_cases(tmp_path, tiny_dataset):
    """(argv, the path named in the error) for each command given an output it cannot write."""
    task = tmp_path / "tiny.toml"
    task.write_text(TINY)
    afile = tmp_path / "a_file"
    afile.write_text("keep")
    rrd = tmp_path / "r.rrd"
    rrd.write_bytes(b"x")
    run = tmp_path / "done"
    assert main(["run", str(task), "--detector", "oracle", "--out", str(run), "--quiet"]) == 0
    root, _ = tiny_dataset
    ro = "/sys/kgn_bench_out"  # sysfs: not writable, even by root
    return [
        (["run", str(task), "--detector", "oracle", "--out", str(afile), "--quiet"], str(afile)),
        (["run", str(task), "--detector", "oracle", "--out", ro, "--quiet"], ro),
        (["data", "generate", "--mode", "single", "--scenes", "1", "--out", ro, "--quiet"], ro),
        (["eval", "vision", "--weights", "kgnv2", "--data", str(root), "--views", "1", "--out", ro, "--quiet"], ro),
        (["report", str(run), "--out", str(afile)], str(afile)),
        (["benchmark", "--detectors", "oracle", "--tasks", "single_object", "--runs", ro, "--quiet"], ro),
        (["replay", str(rrd), "--save", f"{ro}/copy.rrd"], ro),
        (["check", str(run), "--baseline", f"{ro}/b.json", "--update-baseline"], ro),
        (["experiment", "table1", "--out", str(afile)], str(afile)),
    ]


def test_an_unwritable_output_is_one_line_before_any_work(tmp_path, tiny_dataset, capsys):
    for argv, named in _unwritable_cases(tmp_path, tiny_dataset):
        capsys.readouterr()
        before = sorted(p.name for p in tmp_path.iterdir())
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("kgn-bench: error: ") and err.count("\n") == 1 and named in err, (argv, err)
        assert "is a file" in err or "not writable" in err, err
        assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert (tmp_path / "a_file").read_text() == "keep"


def test_too_many_workers_is_a_warning(tmp_path, capsys):
    from kgn_bench.threads import available_cores

    task = tmp_path / "tiny.toml"
    task.write_text(TINY)
    assert main(["run", str(task), "--detector", "oracle", "--workers", "99", "--out", str(tmp_path / "r"),
                 "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err == (f"kgn-bench: warning: --workers 99 is more than the {available_cores()} core(s) of this machine; "
                   f"trials will queue and run slower than with --workers {available_cores()}\n")
