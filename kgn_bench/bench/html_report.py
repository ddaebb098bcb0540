"""The report as a static HTML page (``benchmark.html``) that opens from disk in any browser.

The page is the Markdown report (``report.build_report``: the tables with their Wilson intervals, the hard
tier, GIGA's protocol beside GIGA's Table I, failure reasons per detector, per-object rates, the environment
line) turned into HTML by Python-Markdown with its ``tables`` extension, with the bar chart beside it and a
section of replays: every run folder that holds a rerun recording gets a link to it and the command that
opens it. Nothing is fetched from the
network: the style is inline and images are files next to the page.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any

import markdown

from kgn_bench.io import atomic_write_text

__all__ = ["page", "write_html"]

STYLE = """
body { font-family: system-ui, sans-serif; margin: 2rem auto; max-width: 90rem; padding: 0 1rem; color: #222; }
table { border-collapse: collapse; margin: 1rem 0; font-size: 0.9rem; }
th, td { border: 1px solid #ccc; padding: 0.25rem 0.5rem; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
tr:nth-child(even) td { background: #fafafa; }
img { max-width: 100%; }
code { background: #f3f3f3; padding: 0 0.2rem; }
.replays li { margin: 0.2rem 0; }
"""


def _replays(summaries: list[dict[str, Any]], out: Path) -> str:
    items = []
    for s in summaries:
        recording = Path(str(s["run"])) / "recording.rrd"
        if recording.is_file():
            link = Path(os.path.relpath(recording.resolve(), out.resolve())).as_posix()
            command = f"kgn-bench replay {html.escape(str(s['run']))}"
            items.append(f'<li><a href="{html.escape(link)}">{html.escape(s["detector"])} on '
                         f'{html.escape(s["task"])}</a>: <code>{command}</code></li>')
    if not items:
        return ("<h2>Replays</h2><p>No run of this report was recorded; rerun one with <code>--record</code>, then "
                "<code>kgn-bench replay RUN</code> opens it in the rerun viewer.</p>")
    return '<h2>Replays</h2><ul class="replays">' + "".join(items) + "</ul>"


def page(text: str, summaries: list[dict[str, Any]], out: Path, chart: str | None = "benchmark.png") -> str:
    """The HTML page of the Markdown report ``text`` for a report written to ``out``."""
    body = markdown.markdown(text, extensions=["tables"], output_format="html")
    figure = f'<h2>Chart</h2><img src="{chart}" alt="success and clear rates per detector">' if chart else ""
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<title>KGN-Bench closed-loop benchmark</title>"
            f"<style>{STYLE}</style></head><body>\n{body}\n{figure}\n{_replays(summaries, out)}\n</body></html>\n")


def write_html(text: str, summaries: list[dict[str, Any]], out: Path) -> Path:
    """Write ``out/benchmark.html`` (atomically) and return its path."""
    path = Path(out) / "benchmark.html"
    atomic_write_text(path, page(text, summaries, Path(out)))
    return path
