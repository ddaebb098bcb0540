"""Progress bars: tqdm lines in a log, the rates as postfix, silence when disabled."""

import io

from kgn_bench.progress import Progress


def test_a_log_gets_whole_lines_with_counts_and_rates():
    s = io.StringIO()  # not a terminal
    p = Progress(3, "work", unit="trials", stream=s)
    for i in range(3):
        p.update(1, f"success {100 * (i + 1) // 3}%")
    out = s.getvalue()
    assert "\r" not in out and out.endswith("\n")
    last = out.strip().splitlines()[-1]
    assert last.startswith("work: 100%") and "3/3" in last and "trials/s" in last and "success 100%" in last


def test_disabled_prints_nothing():
    quiet = io.StringIO()
    Progress(2, "x", stream=quiet, enabled=False).update(2)
    assert quiet.getvalue() == ""
