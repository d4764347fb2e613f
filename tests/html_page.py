"""An HTML page read back with the standard library's parser (not the code that wrote it):
its title, headings, paragraphs, list items, tables, images, links and every tag used."""

from __future__ import annotations

from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path

BLOCKS = ("title", "h1", "h2", "h3", "p", "li", "th", "td")


@dataclass
class Page:
    """What a page says, as text (entities decoded, whitespace collapsed)."""

    title: str = ""
    headings: list[str] = field(default_factory=list)
    paragraphs: list[str] = field(default_factory=list)
    items: list[str] = field(default_factory=list)
    tables: list[list[list[str]]] = field(default_factory=list)  # table -> row -> cell
    images: list[dict[str, str]] = field(default_factory=list)
    links: list[dict[str, str]] = field(default_factory=list)
    tags: set[str] = field(default_factory=set)
    meta: dict[str, str] = field(default_factory=dict)

    def table_with(self, header: str) -> list[list[str]]:
        """The rows (header first) of the table whose first header cell is ``header``."""
        return next(table for table in self.tables if table[0][0] == header)


class _Reader(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.page = Page()
        self._open: list[tuple[str, list[str]]] = []  # the blocks being read, and their text

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = {name: value or "" for name, value in attrs}
        self.page.tags.add(tag)
        if tag == "img":
            self.page.images.append(values)
        elif tag == "a":
            self.page.links.append(values)
        elif tag == "meta" and "name" in values:
            self.page.meta[values["name"]] = values.get("content", "")
        elif tag == "table":
            self.page.tables.append([])
        elif tag == "tr":
            self.page.tables[-1].append([])
        if tag in BLOCKS:
            self._open.append((tag, []))

    def handle_data(self, data: str) -> None:
        for _, text in self._open:
            text.append(data)

    def handle_endtag(self, tag: str) -> None:
        if tag not in BLOCKS:
            return
        name, parts = self._open.pop()
        assert name == tag, f"</{tag}> closes <{name}>"
        text = " ".join("".join(parts).split())
        if tag == "title":
            self.page.title = text
        elif tag in ("h1", "h2", "h3"):
            self.page.headings.append(text)
        elif tag == "p":
            self.page.paragraphs.append(text)
        elif tag == "li":
            self.page.items.append(text)
        else:
            self.page.tables[-1][-1].append(text)


def read_page(source: str | Path) -> Page:
    """The page in ``source``: a path, or the HTML text itself."""
    text = Path(source).read_text(encoding="utf-8") if isinstance(source, Path) else source
    reader = _Reader()
    reader.feed(text)
    reader.close()
    return reader.page
