"""Every report page is written twice from the same Markdown lines: NAME.md for a text
editor or a repository, NAME.html for a browser.

The HTML is rendered by markdown-it-py (CommonMark with pipe tables), with raw HTML turned
off so that every text from a record (its notes, a file name) is shown, never run.  The
page is self-contained apart from the PNG figures it links by relative path: no script, no
external style or font (reports are read offline).  A link to another Markdown page goes to
that page's HTML twin.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from html import escape
from pathlib import Path
from urllib.parse import urlsplit

from markdown_it import MarkdownIt
from markdown_it.token import Token

from analysis.provenance import PACKAGE, package_version

IMAGE_WIDTH_PX = 800  # figures are 1600 px wide (analysis.figure_style): sharp at half size

STYLE = """\
body { font-family: sans-serif; max-width: 64rem; margin: 2rem auto; padding: 0 1rem;
       line-height: 1.45; color: #111; }
table { border-collapse: collapse; margin: 1rem 0; }
th, td { border: 1px solid #bbb; padding: 0.25rem 0.5rem; text-align: left;
         vertical-align: top; }
th { background: #eee; }
code { background: #f2f2f2; padding: 0 0.2rem; }
img { max-width: 100%; height: auto; }
hr { margin-top: 2rem; }"""

_HEADING = re.compile(r"#{1,6} (.*)")


def write_page(lines: Sequence[str], path: str | Path) -> Path:
    """Write the Markdown ``lines`` to ``path`` (NAME.md) and their HTML to NAME.html beside
    it; returns the Markdown page's path."""
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    path.with_suffix(".html").write_text(markdown_to_html(lines), encoding="utf-8")
    return path


def markdown_to_html(lines: Sequence[str]) -> str:
    """The HTML document of a page's Markdown lines, titled by its first heading."""
    title = next((m.group(1) for m in map(_HEADING.fullmatch, lines) if m), "impact-rig report")
    renderer = MarkdownIt("commonmark", {"html": False}).enable("table")
    tokens = renderer.parse("\n".join(lines))
    for token in _inline_children(tokens):
        if token.type == "image":
            token.attrSet("width", str(IMAGE_WIDTH_PX))
        elif token.type == "link_open":
            token.attrSet("href", _html_twin(str(token.attrGet("href"))))
    body = renderer.renderer.render(tokens, renderer.options, {})
    head = [
        "<!DOCTYPE html>",
        '<html lang="en">',
        "<head>",
        '<meta charset="utf-8">',
        f'<meta name="generator" content="{escape(f"{PACKAGE} {package_version()}")}">',
        f"<title>{escape(re.sub(r'[`*]', '', title), quote=False)}</title>",
        f"<style>\n{STYLE}\n</style>",
        "</head>",
        "<body>",
    ]
    return "\n".join([*head, body.rstrip("\n"), "</body>", "</html>"]) + "\n"


def _inline_children(tokens: list[Token]) -> list[Token]:
    """Every token inside the inline runs (where links and images live)."""
    return [child for token in tokens if token.type == "inline" for child in token.children or ()]


def _html_twin(href: str) -> str:
    """A relative link to a Markdown page goes to its HTML twin, written beside it."""
    parts = urlsplit(href)
    if not parts.scheme and not parts.netloc and parts.path.endswith(".md"):
        return parts._replace(path=parts.path[: -len(".md")] + ".html").geturl()
    return href
