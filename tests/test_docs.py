"""The README and docs/: every relative link and #anchor resolves, so a reader following
them never lands on nothing; and docs/ reads as documentation for users, not as a lab
notebook: no dated headings, no problem ids, no paths outside the repository, a size
limit, and the history in CHANGELOG.md at the repository's root."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
FENCE = re.compile(r"```.*?```", flags=re.S)
# An explicit HTML anchor, which GitHub renders as a link target like a heading's.
HTML_ANCHOR = re.compile(r"<a\s+(?:id|name)=\"([^\"]+)\"")

# docs/*.md, results.md excluded, in bytes (results.md is the measurements' page: long
# tables, one per question).
DOCS_LIMIT = 120_000
RESULTS = "results.md"

# A heading that carries a date: the page is a diary entry, not documentation.
DATED_HEADING = re.compile(r"^#+ .*\b\d{4}-\d{2}-\d{2}\b.*$", flags=re.M)
# A problem of a problem set named by its directory (p023, P162): meaningless to a reader
# who has not got that set. Checked over the whole page, code blocks included.
PROBLEM_ID = re.compile(r"\b[pP]\d{3}\b")
# A path outside the repository that a clone does not have. Checked in the text outside
# fenced code blocks (prose and inline code); a fenced block may show any path a command
# takes as an example. The rule: an absolute path under /work, /tmp, /home, /root or /mnt,
# or a run folder of a past session, runs/S<N> (paths a command writes, such as out/... or
# data_out/..., and user paths such as ~/.ray/auth_token are fine).
FOREIGN_PATH = re.compile(r"(?<![\w.~])(?:/(?:work|tmp|home|root|mnt)/|runs/S\d+\b)")


def pages() -> list[Path]:
    return [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def docs_pages(root: Path = REPO) -> list[Path]:
    return sorted((root / "docs").glob("*.md"))


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: lowercase, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def anchors(page: Path) -> set[str]:
    text = FENCE.sub("", page.read_text())
    return ({slug(m) for m in re.findall(r"^#+ (.+)$", text, flags=re.M)}
            | set(HTML_ANCHOR.findall(text)))


def broken_links(page: Path) -> list[str]:
    text = FENCE.sub("", page.read_text())
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


def dated_headings(page: Path) -> list[str]:
    return [m.group(0) for m in DATED_HEADING.finditer(FENCE.sub("", page.read_text()))]


def problem_ids(page: Path) -> list[str]:
    return PROBLEM_ID.findall(page.read_text())


def foreign_paths(page: Path) -> list[str]:
    text = FENCE.sub("", page.read_text())
    return [line.strip() for line in text.splitlines() if FOREIGN_PATH.search(line)]


def docs_size(root: Path = REPO) -> int:
    """Bytes of docs/*.md, the results page excluded."""
    return sum(len(p.read_bytes()) for p in docs_pages(root) if p.name != RESULTS)


def changelog_missing(root: Path = REPO) -> bool:
    return not (root / "CHANGELOG.md").is_file()


def found(check) -> dict[str, list[str]]:
    hits = {str(p.relative_to(REPO)): check(p) for p in docs_pages()}
    return {p: h for p, h in hits.items() if h}


def test_every_relative_link_and_anchor_resolves():
    broken = {str(p.relative_to(REPO)): broken_links(p) for p in pages()}
    assert {p: b for p, b in broken.items() if b} == {}


def test_the_checker_finds_a_broken_link_and_anchor(tmp_path):
    (tmp_path / "a.md").write_text("# The closed loop: `symplan solve`\n<a id=\"old-name\"></a>\n")
    page = tmp_path / "b.md"
    page.write_text("[ok](a.md#the-closed-loop-symplan-solve) [x](a.md#nope) [y](none.md)\n"
                    "[web](https://example.org/x) [self](#here) [kept](a.md#old-name)\n\n"
                    "## Here\n")
    assert broken_links(page) == ["a.md#nope (no heading #nope)", "none.md (no file)"]


def test_no_heading_in_docs_carries_a_date():
    assert found(dated_headings) == {}


def test_the_checker_finds_a_dated_heading(tmp_path):
    page = tmp_path / "bad.md"
    page.write_text("# Planning\n\n## Long goals (2026-11-28)\n\nMeasured on 2026-11-28.\n"
                    "```\n# 2026-11-29 in a code block\n```\n")
    assert dated_headings(page) == ["## Long goals (2026-11-28)"]


def test_no_page_in_docs_names_a_problem_by_its_id():
    assert found(problem_ids) == {}


def test_the_checker_finds_a_problem_id(tmp_path):
    page = tmp_path / "bad.md"
    page.write_text("Traced on p023 and the P162 set; p0(x), p95 and p1000 are fine.\n")
    assert problem_ids(page) == ["p023", "P162"]


def test_no_page_in_docs_names_a_path_outside_the_repository():
    assert found(foreign_paths) == {}


def test_the_checker_finds_a_path_outside_the_repository(tmp_path):
    page = tmp_path / "bad.md"
    page.write_text("Solved on `runs/S26/L/towers` here.\nLogs in /tmp/x.\n"
                    "Fine: out/runs/rel_s0, data_out/hand3k_s12, ~/.ray/auth_token.\n"
                    "```bash\nsymplan collect --out /tmp/data\n```\n")
    assert foreign_paths(page) == ["Solved on `runs/S26/L/towers` here.", "Logs in /tmp/x."]


def test_docs_stay_within_their_size_limit():
    assert docs_size() <= DOCS_LIMIT


def test_the_size_counts_every_page_but_the_results(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "a.md").write_text("x" * (DOCS_LIMIT + 1))
    (tmp_path / "docs" / RESULTS).write_text("y" * 10)
    assert docs_size(tmp_path) == DOCS_LIMIT + 1 > DOCS_LIMIT


def test_the_history_is_in_a_changelog_at_the_root():
    assert not changelog_missing()


def test_the_checker_finds_a_missing_changelog(tmp_path):
    assert changelog_missing(tmp_path)
    (tmp_path / "CHANGELOG.md").write_text("# Changelog\n")
    assert not changelog_missing(tmp_path)
