"""The README's and docs/'s links lead somewhere: each relative link to a file in the repository and
each anchor (``#...``, in-page or on another page) to a heading of that page, by GitHub's rule for
heading anchors. The README summarises the accuracy and speed figures and the commands and links the
measurements and the full command reference behind them (docs/, docs/commands/), so a link that breaks
in a move leaves a reader with a figure or a summary and no evidence."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)\s]+)\)")
FENCE = re.compile(r"^\s*(```|~~~)")
# a message's or --help's pointer to a section: README 'Heading' or docs/commands/diagnose.md: 'Heading'
SECTION = re.compile(r"\b(README|docs/[\w/-]+\.md):? '([^']+)'")
PACKAGES = ("cli", "diagnose", "expdesign", "identify", "maps", "primitives")


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _prose(md: Path) -> list[str]:
    """The page's lines outside fenced and indented code blocks."""
    out, fenced = [], False
    for line in md.read_text(encoding="utf-8").splitlines():
        if FENCE.match(line):
            fenced = not fenced
        elif not fenced and not line.startswith("    "):
            out.append(line)
    return out


def anchor(heading: str) -> str:
    """GitHub's anchor of a heading: its text as rendered (code marks, link targets, emphasis dropped),
    lower case, every character but letters, digits, '_', '-' and spaces removed, spaces made '-'."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = re.sub(r"[`*]", "", text).strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(md: Path) -> set[str]:
    """Every anchor of a page: its headings' (a repeated one numbered -1, -2, ... as GitHub does)."""
    seen: dict[str, int] = {}
    out = set()
    for line in _prose(md):
        if m := re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line):
            a = anchor(m.group(1))
            out.add(f"{a}-{seen[a]}" if a in seen else a)
            seen[a] = seen.get(a, 0) + 1
    return out


def _links(md: Path) -> list[str]:
    """Link targets, inline code spans left out (no link there)."""
    spans = [re.sub(r"`[^`]*`", "``", line) for line in _prose(md)]
    return [t for line in spans for t in LINK.findall(line) if "://" not in t and not t.startswith("mailto:")]


def broken_links(pages: list[Path], root: Path = ROOT) -> list[str]:
    broken = []
    for md in pages:
        for target in _links(md):
            path, _, frag = target.partition("#")
            dest = (md.parent / path).resolve() if path else md
            if not dest.exists():
                broken.append(f"{md.relative_to(root)} -> {target}: no such file")
            elif frag and dest.suffix == ".md" and frag not in anchors(dest):
                broken.append(f"{md.relative_to(root)} -> {target}: no such heading")
    return broken


def test_every_relative_link_and_anchor_in_the_readme_and_docs_resolves():
    broken = broken_links(_pages())
    assert not broken, broken


def test_a_broken_anchor_or_file_is_found(tmp_path):
    """The check itself: a dead anchor, a dead file and a heading's GitHub anchor."""
    page = tmp_path / "p.md"
    page.write_text(
        "# A `cmd`: the (first) one\n\n## Twice\n\n## Twice\n\n[ok](#a-cmd-the-first-one) [ok](#twice-1)\n"
        "[dead](#nowhere) [dead](q.md) [dead](p.md#twice-2)\n`[code](#not-a-link)`\n",
        encoding="utf-8",
    )
    found = broken_links([page], tmp_path)
    assert found == ["p.md -> #nowhere: no such heading", "p.md -> q.md: no such file", "p.md -> p.md#twice-2: no such heading"]


def test_the_readme_links_each_docs_page():
    """A page in docs/ that neither the README nor the command index links is one a reader never finds."""
    index = ROOT / "docs" / "commands" / "README.md"
    linked = {(md.parent / t.partition("#")[0]).resolve() for md in (ROOT / "README.md", index) for t in _links(md)}
    assert {p.resolve() for p in (ROOT / "docs").rglob("*.md")} - {index.resolve()} <= linked
    assert index.resolve() in linked


def named_sections(src: str) -> list[tuple[str, str]]:
    """The (page, heading) pairs the string literals of a module name; adjacent literals, which a long
    message or --help is split into, count as the one string Python makes of them."""
    texts = [n.value for n in ast.walk(ast.parse(src)) if isinstance(n, ast.Constant) and isinstance(n.value, str)]
    return [("README.md" if page == "README" else page, h) for s in texts for page, h in SECTION.findall(" ".join(s.split()))]


def test_every_section_a_message_or_help_names_exists():
    """Error messages and --help send a user to a section by its heading ("docs/commands/detect.md:
    'Recordings for detect and detect-prior'"): a heading renamed or moved leaves the user looking for
    nothing. At stop 62 the sections these named moved out of the README."""
    named = {
        (f"{py.relative_to(ROOT)}", page, h)
        for pkg in PACKAGES
        for py in sorted((ROOT / pkg).rglob("*.py"))
        if re.search(r"README|docs/", src := py.read_text(encoding="utf-8"))  # parse only the modules that may name one
        for page, h in named_sections(src)
    }
    missing = [
        f"{py} -> {page}: '{h}'"
        for py, page, h in sorted(named)
        if not (ROOT / page).exists() or anchor(h) not in anchors(ROOT / page)
    ]
    assert not missing, missing
    assert len(named) >= 5  # the pattern still finds the messages' pointers
