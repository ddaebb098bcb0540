"""kgn-bench run (kgn_bench.cli.run): its help, a bundled task by name from any folder."""

import pytest

from kgn_bench.cli import main


def test_trials_help_says_what_it_counts(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "per object for single_object tasks" in text and "scenes for multi_object tasks" in text


def test_a_bundled_task_runs_by_name_from_anywhere(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "ci_oracle", "--detector", "oracle", "--trials", "1", "--out", "r", "--quiet"]) == 0
    assert "# ci_oracle: oracle" in capsys.readouterr().out
