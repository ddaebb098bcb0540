import io

from kgn_bench.progress import Progress


def test_progress_prints_final_line_with_counts():
    s = io.StringIO()
    p = Progress(3, "work", unit="it", stream=s)
    for _ in range(3):
        p.update()
    out = s.getvalue()
    assert "3/3" in out and out.endswith("\n")
    quiet = io.StringIO()
    Progress(2, "x", stream=quiet, enabled=False).update(2)
    assert quiet.getvalue() == ""
