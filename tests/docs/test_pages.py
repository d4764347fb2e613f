"""The documentation pages stay true: a README a newcomer reads in five minutes, the marker CI
reads the test command from, and no relative link or image pointing to a file that is not
there (README.md, CHANGELOG.md and every page in docs/)."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
README_MAX_LINES = 200
PAGES = [README, ROOT / "CHANGELOG.md", *sorted(DOCS.glob("*.md"))]


def link_targets(text: str) -> list[str]:
    """Every link's href and image's src in a Markdown text, as CommonMark parses it."""
    targets = []
    for token in MarkdownIt("commonmark").enable("table").parse(text):
        for child in token.children or ():
            if child.type == "link_open":
                targets.append(str(child.attrGet("href")))
            elif child.type == "image":
                targets.append(str(child.attrGet("src")))
    return targets


def missing_targets(page: Path) -> list[str]:
    """The relative links and images of ``page`` whose file does not exist."""
    missing = []
    for target in link_targets(page.read_text(encoding="utf-8")):
        parts = urlsplit(target)
        if parts.scheme or parts.netloc or not parts.path:  # a web address, or #anchor only
            continue
        if not (page.parent / unquote(parts.path)).exists():
            missing.append(target)
    return missing


def test_readme_is_at_most_200_lines():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f"README.md has {len(lines)} lines (at most {README_MAX_LINES}): move detail to docs/"
    )


def fenced_line_after(marker: str) -> str:
    """The first line of the fence right after ``marker``, as .ci/run reads it with awk."""
    lines = README.read_text(encoding="utf-8").splitlines()
    assert marker in lines, f"README.md lost its {marker} marker"
    at = lines.index(marker)
    assert lines[at + 1].startswith("```"), f"README.md: no fenced block right after {marker}"
    return lines[at + 2]


def test_readme_keeps_the_test_command_ci_runs():
    assert "pytest" in fenced_line_after("<!-- test-command -->")


def test_readme_keeps_the_main_command():
    assert "impact-rig demo" in fenced_line_after("<!-- main-command -->")


@pytest.mark.parametrize("page", PAGES, ids=lambda page: str(page.relative_to(ROOT)))
def test_relative_links_and_images_point_to_files_that_exist(page):
    assert missing_targets(page) == [], f"{page.relative_to(ROOT)}: broken links"


def test_the_index_links_every_page():
    linked = {
        (DOCS / unquote(urlsplit(target).path)).resolve()
        for target in link_targets((DOCS / "index.md").read_text(encoding="utf-8"))
    }
    unlinked = [p.name for p in DOCS.glob("*.md") if p.name != "index.md" and p not in linked]
    assert unlinked == [], f"docs/index.md does not link {unlinked}"


def test_a_missing_file_is_found_in_text_tables_and_images(tmp_path):
    (tmp_path / "there.md").write_text("x")
    page = tmp_path / "page.md"
    page.write_text(
        "[ok](there.md#part) [web](https://example.org/x.md) [anchor](#top)\n\n"
        "![gone](figures/gone.png)\n\n| a | b |\n|---|---|\n| [cell](nowhere.md) | x |\n",
        encoding="utf-8",
    )
    assert missing_targets(page) == ["figures/gone.png", "nowhere.md"]
