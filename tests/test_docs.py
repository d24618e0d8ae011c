"""The README and docs/: every relative link and #anchor resolves, so a reader following
them never lands on nothing."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def pages() -> list[Path]:
    return [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lowercase, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    return {slug(m) for m in re.findall(r"^#+ (.+)$", text, flags=re.M)}


def broken_links(page: Path) -> list[str]:
    text = re.sub(r"```.*?```", "", page.read_text(), flags=re.S)
    broken = []
    for target in LINK.findall(text):
        if re.match(r"^[a-z]+:", target):  # http(s), mailto: not ours to check
            continue
        path, _, anchor = target.partition("#")
        file = (page.parent / path).resolve() if path else page
        if not file.exists():
            broken.append(f"{target} (no file)")
        elif anchor and file.suffix == ".md" and anchor not in anchors(file):
            broken.append(f"{target} (no heading #{anchor})")
    return broken


def test_every_relative_link_and_anchor_resolves():
    found = {str(p.relative_to(REPO)): broken_links(p) for p in pages()}
    assert {p: b for p, b in found.items() if b} == {}


def test_the_checker_finds_a_broken_link_and_anchor(tmp_path):
    (tmp_path / "a.md").write_text("# The closed loop: `symplan solve`\n")
    page = tmp_path / "b.md"
    page.write_text("[ok](a.md#the-closed-loop-symplan-solve) [x](a.md#nope) [y](none.md)\n"
                    "[web](https://example.org/x) [self](#here)\n\n## Here\n")
    assert broken_links(page) == ["a.md#nope (no heading #nope)", "none.md (no file)"]
