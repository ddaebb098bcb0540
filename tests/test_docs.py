"""README as a front page, the documentation site's sources, and the generated task-file reference."""

from __future__ import annotations

import dataclasses
import importlib.util
import inspect
import re
from pathlib import Path

import pytest

from kgn_bench import config

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
LINK = re.compile(r"\]\(([^)\s]+)\)")


def _hook(name: str):
    spec = importlib.util.spec_from_file_location(f"docs_hook_{name}", ROOT / "docs" / "hooks" / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _relative_links(text: str) -> list[str]:
    targets = [m.group(1).split("#")[0] for m in LINK.finditer(text)]
    return [t for t in targets if t and "://" not in t and not t.startswith("mailto:")]


def test_readme_is_a_front_page():
    lines = README.read_text().splitlines()
    assert len(lines) <= 200, f"README has {len(lines)} lines"
    heading = [i for i, line in enumerate(lines, 1) if line.strip() == "## Your own detector"]
    assert heading and heading[0] <= 120, "'Your own detector' must start within README's first 120 lines"
    assert "make benchmark" in README.read_text() and "make test" in README.read_text()


def test_every_relative_link_in_readme_points_to_a_file_in_the_repository():
    links = _relative_links(README.read_text())
    assert links, "README links to nothing"
    for target in links:
        path = (ROOT / target).resolve()
        assert path.is_relative_to(ROOT), f"README links outside the repository: {target}"
        assert path.exists(), f"README links to a missing file: {target}"


def test_every_relative_link_of_the_docs_pages_points_to_a_file_in_the_repository():
    pages = sorted((ROOT / "docs").rglob("*.md"))
    assert len(pages) >= 20
    for page in pages:
        for target in _relative_links(page.read_text()):
            path = (page.parent / target).resolve()
            assert path.is_relative_to(ROOT), f"{page.relative_to(ROOT)} links outside the repository: {target}"
            assert path.exists(), f"{page.relative_to(ROOT)} links to a missing file: {target}"


def test_every_nav_page_exists():
    nav = re.findall(r":\s*([\w/.-]+\.md)\s*$", (ROOT / "mkdocs.yml").read_text(), flags=re.M)
    assert "task-file.md" in nav and "api/config.md" in nav
    for page in nav:
        assert (ROOT / "docs" / page).exists() or (ROOT / page).exists(), page


def _reference_fields(markdown: str) -> dict[str, set[str]]:
    """Class name -> the field names listed (second column) in the sections that document that class."""
    out: dict[str, set[str]] = {}
    for section in markdown.split("### ")[1:]:
        cls = re.search(r"Dataclass `kgn_bench\.config\.(\w+)`", section).group(1)
        rows = [line for line in section.splitlines() if line.startswith("| `")]
        out.setdefault(cls, set()).update(re.match(r"\| [^|]+ \| `(\w+)` \|", row).group(1) for row in rows)
    return out


def test_the_generated_task_reference_lists_every_field_of_every_config_dataclass():
    markdown = _hook("task_reference").reference_markdown()
    listed = _reference_fields(markdown)
    classes = [c for _, c in inspect.getmembers(config, inspect.isclass)
               if dataclasses.is_dataclass(c) and c.__module__ == config.__name__]
    assert {c.__name__ for c in classes} == set(listed)
    for cls in classes:
        assert listed[cls.__name__] == {f.name for f in dataclasses.fields(cls)}, cls.__name__
    # Each row gives the default and a meaning; the TOML key of a renamed field is the task file's.
    assert "| `per_scene` | `objects_per_scene` | int | `5` |" in markdown
    assert "| `depth_noise` | `depth_noise` | float | `0.0` | `depth_noise`: strength of the depth model" in markdown
    assert all(not row.rstrip().endswith("|  |") for row in markdown.splitlines() if row.startswith("| `"))


def test_the_task_reference_refuses_a_note_for_a_field_that_does_not_exist(monkeypatch):
    hook = _hook("task_reference")
    monkeypatch.setitem(hook.NOTES, ("SelectorConfig", "no_such_field"), "stale")
    with pytest.raises(ValueError, match="no_such_field"):
        hook.reference_markdown()


def test_the_task_reference_replaces_its_marker_on_its_page_only():
    hook = _hook("task_reference")

    class Page:
        def __init__(self, uri):
            self.file = type("F", (), {"src_uri": uri})()

    page = "intro\n\n" + hook.MARKER + "\n"
    assert "### `[selector]`" in hook.on_page_markdown(page, Page("task-file.md"), None, None)
    assert hook.on_page_markdown(page, Page("index.md"), None, None) == page


def test_links_out_of_docs_are_rewritten_to_the_served_copies():
    rewrite = _hook("repo_files").rewrite_links
    served = {"results/benchmark.md", "results/errors/kgn/errors.png", "CHANGELOG.md"}
    text = ("[r](../results/benchmark.md#hard-tier) ![e](../../results/errors/kgn/errors.png) "
            "[c](../CHANGELOG.md) [p](protocols.md) [x](../tasks/pile.toml) [w](https://example.org/a.md)")
    top = rewrite(text.replace("../../results", "../results"), "results.md", served)
    assert "[r](results/benchmark.md#hard-tier)" in top and "![e](results/errors/kgn/errors.png)" in top
    assert "[c](CHANGELOG.md)" in top and "[p](protocols.md)" in top and "[x](../tasks/pile.toml)" in top
    nested = rewrite(text, "studies/viewpoints.md", served)
    assert "![e](../results/errors/kgn/errors.png)" in nested and "[w](https://example.org/a.md)" in nested


def _report_rows(lines: list[str], header_start: str) -> dict[str, dict[str, str]]:
    """The table of ``results/benchmark.md`` whose header starts so: detector -> column -> cell."""
    i = next(k for k, line in enumerate(lines) if line.startswith(header_start))
    header = [c.strip() for c in lines[i].strip("|").split("|")]
    out = {}
    for line in lines[i + 2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        out[cells[0]] = dict(zip(header, cells))
    return out


def test_readme_headline_table_is_the_reports_current_figures():
    lines = (ROOT / "results" / "benchmark.md").read_text().splitlines()
    loop, hard = _report_rows(lines, "| detector | single, primitives"), _report_rows(lines, "| detector | packed GSR")
    columns = [(loop, "single, primitives"), (loop, "single, household"), (loop, "multi success"),
               (loop, "single, real objects"), (hard, "pile GSR"), (hard, "pile DR"), (hard, "packed GSR")]
    for detector in ("kgnv2", "kgn", "kgn_depth", "antipodal", "random", "oracle"):
        cells = [re.sub(r" \[[^\]]*\]", "", table[detector][column]) for table, column in columns]
        row = "| " + " | ".join([detector, *cells]) + " |"
        assert row in README.read_text(), f"README's {detector} row is not results/benchmark.md's: {row}"
        assert row in (ROOT / "docs" / "results.md").read_text(), detector
