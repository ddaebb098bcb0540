"""MkDocs hook: serve the repository's measured results and its changelog from where they live.

``results/`` (reports, tables, figures) and ``CHANGELOG.md`` stay outside ``docs/``, so the site holds no copy
of a measured figure that could drift. ``on_files`` adds them to the build under their repository paths
(``results/benchmark.md`` is the page ``results/benchmark/``), and ``on_page_markdown`` rewrites a page's
relative link that points out of ``docs/`` at one of them (``../results/benchmark.md``, a link that also works
when the Markdown is read on a code host) into the link between the two files in the built site.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path

SERVED_DIRS = ("results",)
SERVED_FILES = ("CHANGELOG.md",)
SUFFIXES = {".md", ".png", ".json", ".csv", ".html"}
LINK = re.compile(r"(!?\[[^\]]*\])\(([^)\s#]+)(#[^)\s]*)?\)")


def _root(config) -> Path:
    return Path(config.config_file_path).resolve().parent


def _served(root: Path) -> list[str]:
    """Repository paths (POSIX, relative to the root) of every file the site serves from outside ``docs/``."""
    out = [name for name in SERVED_FILES if (root / name).is_file()]
    for folder in SERVED_DIRS:
        out += sorted(p.relative_to(root).as_posix() for p in (root / folder).rglob("*")
                      if p.is_file() and p.suffix in SUFFIXES)
    return out


def on_files(files, config):
    from mkdocs.structure.files import File  # here, so that rewrite_links is usable (and tested) without mkdocs

    root = _root(config)
    for path in _served(root):
        files.append(File(path, src_dir=str(root), dest_dir=config.site_dir,
                          use_directory_urls=config.use_directory_urls))
    return files


def rewrite_links(markdown: str, page_uri: str, served: set[str]) -> str:
    """``markdown`` of the page at ``docs/<page_uri>`` with every relative link that resolves (from that page
    in the repository) to a served path made relative to the page inside the site; other links unchanged."""
    here = posixpath.dirname(f"docs/{page_uri}")
    site_dir = posixpath.dirname(page_uri) or "."

    def swap(m: re.Match) -> str:
        text, target, anchor = m.group(1), m.group(2), m.group(3) or ""
        if "://" in target or target.startswith("/"):
            return m.group(0)
        repo_path = posixpath.normpath(posixpath.join(here, target))
        if repo_path not in served:
            return m.group(0)
        return f"{text}({posixpath.relpath(repo_path, site_dir)}{anchor})"

    return LINK.sub(swap, markdown)


def on_page_markdown(markdown, page, config, files):
    if not page.file.src_uri.startswith(tuple(f"{d}/" for d in SERVED_DIRS)) and page.file.src_uri not in SERVED_FILES:
        return rewrite_links(markdown, page.file.src_uri, set(_served(_root(config))))
    return markdown
