"""Every report page is written twice from the same Markdown lines: NAME.md for a text
editor or a repository, NAME.html for a browser.

The HTML comes from a renderer of exactly the Markdown our pages use (headings, paragraphs,
one-level lists, pipe tables, images, links, inline code, bold, italic, rules), so the two
never say different things.  The page is self-contained apart from the PNG figures it
links by relative path: no script, no external style or font (reports are read offline).
Every text is escaped; a link to another Markdown page goes to that page's HTML twin.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator, Sequence
from html import escape
from pathlib import Path
from urllib.parse import urlsplit

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

_HEADING = re.compile(r"(#{1,6}) (.*)")
_SEPARATOR_CELL = re.compile(r":?-+:?")
_INLINE = re.compile(
    r"`(?P<code>[^`]+)`"
    r"|!\[(?P<alt>[^\]]*)\]\((?P<src>[^)\s]+)\)"
    r"|\[(?P<text>[^\]]+)\]\((?P<href>[^)\s]+)\)"
    r"|\*\*(?P<strong>.+?)\*\*"
    r"|\*(?P<em>[^*\s](?:[^*]*[^*\s])?)\*"
)


def write_page(lines: Sequence[str], path: str | Path) -> Path:
    """Write the Markdown ``lines`` to ``path`` (NAME.md) and their HTML to NAME.html beside
    it; returns the Markdown page's path."""
    path = Path(path)
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    path.with_suffix(".html").write_text(markdown_to_html(lines), encoding="utf-8")
    return path


def markdown_to_html(lines: Sequence[str]) -> str:
    """The HTML document of a page's Markdown lines, titled by its first heading."""
    title = next((m.group(2) for m in map(_HEADING.fullmatch, lines) if m), "impact-rig report")
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
    return "\n".join([*head, *_blocks(list(lines)), "</body>", "</html>"]) + "\n"


def _blocks(lines: list[str]) -> Iterator[str]:
    """The HTML of each block: heading, rule, list, table or paragraph."""
    i = 0
    while i < len(lines):
        line = lines[i]
        heading = _HEADING.fullmatch(line)
        if not line.strip():
            i += 1
        elif heading:
            level = len(heading.group(1))
            yield f"<h{level}>{inline_html(heading.group(2))}</h{level}>"
            i += 1
        elif line == "---":
            yield "<hr>"
            i += 1
        elif line.startswith("- "):
            end = _run_end(lines, i, lambda text: text.startswith("- "))
            items = "".join(f"<li>{inline_html(item[2:])}</li>\n" for item in lines[i:end])
            yield f"<ul>\n{items}</ul>"
            i = end
        elif _is_table(lines, i):
            end = _run_end(lines, i, lambda text: text.startswith("|"))
            yield _table(lines[i:end])
            i = end
        else:
            end = _run_end(lines, i, lambda text: bool(text.strip()) and not _starts_block(text))
            yield f"<p>{inline_html(' '.join(lines[i:end]))}</p>"
            i = end


def _run_end(lines: list[str], start: int, belongs: Callable[[str], bool]) -> int:
    """The index after the run of lines from ``start`` (which belongs) that ``belongs``."""
    end = start + 1
    while end < len(lines) and belongs(lines[end]):
        end += 1
    return end


def _starts_block(line: str) -> bool:
    return bool(_HEADING.fullmatch(line)) or line == "---" or line.startswith(("- ", "|"))


def _cells(row: str) -> list[str]:
    return [cell.strip() for cell in row.strip().strip("|").split("|")]


def _is_table(lines: list[str], i: int) -> bool:
    """A pipe table: a row of cells, then a row of dashes under each."""
    return (
        lines[i].startswith("|")
        and i + 1 < len(lines)
        and all(_SEPARATOR_CELL.fullmatch(cell) for cell in _cells(lines[i + 1]))
    )


def _table(rows: list[str]) -> str:
    header, body = _cells(rows[0]), [_cells(row) for row in rows[2:]]
    head = "".join(f"<th>{inline_html(cell)}</th>" for cell in header)
    rows_html = "".join(
        "<tr>" + "".join(f"<td>{inline_html(cell)}</td>" for cell in row) + "</tr>\n"
        for row in body
    )
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{rows_html}</tbody>\n</table>"


def inline_html(text: str) -> str:
    """One line of Markdown as HTML: code, images, links, bold and italic; the rest escaped."""
    parts, position = [], 0
    for match in _INLINE.finditer(text):
        parts.append(escape(text[position : match.start()], quote=False))
        parts.append(_inline_element(match))
        position = match.end()
    parts.append(escape(text[position:], quote=False))
    return "".join(parts)


def _inline_element(match: re.Match[str]) -> str:
    found = match.groupdict()
    if found["code"] is not None:
        return f"<code>{escape(found['code'], quote=False)}</code>"
    if found["src"] is not None:
        return (f'<img src="{escape(found["src"])}" alt="{escape(found["alt"])}" '
                f'width="{IMAGE_WIDTH_PX}">')
    if found["href"] is not None:
        return f'<a href="{escape(_html_twin(found["href"]))}">{inline_html(found["text"])}</a>'
    if found["strong"] is not None:
        return f"<strong>{inline_html(found['strong'])}</strong>"
    return f"<em>{inline_html(found['em'])}</em>"


def _html_twin(href: str) -> str:
    """A relative link to a Markdown page goes to its HTML twin, written beside it."""
    parts = urlsplit(href)
    if not parts.scheme and not parts.netloc and parts.path.endswith(".md"):
        return parts._replace(path=parts.path[: -len(".md")] + ".html").geturl()
    return href
