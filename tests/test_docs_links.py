"""The README's and docs/'s relative links lead to files in the repository: the README summarises
the accuracy and speed figures and links the measurements behind them (docs/), so a link that
breaks in a move leaves a reader with a figure and no evidence."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def _relative_links(md: Path) -> list[str]:
    return [t for t in LINK.findall(md.read_text(encoding="utf-8")) if "://" not in t and not t.startswith("mailto:")]


def test_every_relative_link_in_the_readme_and_docs_resolves():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    broken = [f"{md.relative_to(ROOT)} -> {t}" for md in pages for t in _relative_links(md) if not (md.parent / t).exists()]
    assert not broken, broken


def test_the_readme_links_each_docs_page():
    """A page in docs/ that the README does not link is one a reader never finds."""
    linked = {Path(t).name for t in _relative_links(ROOT / "README.md")}
    assert {p.name for p in (ROOT / "docs").glob("*.md")} <= linked
