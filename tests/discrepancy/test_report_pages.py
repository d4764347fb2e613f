"""Report pages: the Markdown lines written as NAME.md and, read back by the standard
library's HTML parser, the same content in NAME.html (escaped, tables as tables)."""

from __future__ import annotations

from analysis.report.pages import markdown_to_html, write_page
from tests.html_page import read_page

LINES = [
    "# Report on <b>run</b> & `decay.csv`",
    "",
    "- **cause: `coulomb_friction`** & more",
    "- an interval that *misses*, a [page](analysis/run.md) and a [site](https://example.org/a.md)",
    "",
    "![fit & residuals](run_fit.png)",
    "",
    "## Ranking",
    "",
    "| cause | parameters [unit] |",
    "|---|---|",
    "| `coulomb_friction` | Tc_N_m = 2e-05 [1.9e-05, 2.1e-05] |",
    "| <script>alert(1)</script> | a & b \"quoted\" |",
    "",
    "A paragraph",
    "over two lines, where 1 < 2.",
    "",
    "---",
    "",
    "Made by impact-rig: `impact-rig analyze run.csv --report out/`",
]


def test_the_html_page_holds_the_markdowns_content_escaped():
    html = markdown_to_html(LINES)
    page = read_page(html)
    assert "<script>" not in html and "<b>" not in html
    assert page.title == "Report on <b>run</b> & decay.csv"
    assert page.headings == ["Report on <b>run</b> & decay.csv", "Ranking"]
    assert "<strong>cause: <code>coulomb_friction</code></strong> &amp; more" in html
    assert page.items == [
        "cause: coulomb_friction & more",
        "an interval that misses, a page and a site",
    ]
    assert "<em>misses</em>" in html
    # a page links to its sibling's HTML twin; an address elsewhere is left alone
    assert page.links == [{"href": "analysis/run.html"}, {"href": "https://example.org/a.md"}]
    assert page.images == [{"src": "run_fit.png", "alt": "fit & residuals", "width": "800"}]
    assert page.tables == [[
        ["cause", "parameters [unit]"],
        ["coulomb_friction", "Tc_N_m = 2e-05 [1.9e-05, 2.1e-05]"],
        ["<script>alert(1)</script>", 'a & b "quoted"'],
    ]]
    assert page.paragraphs == [
        "",  # the paragraph that holds the figure
        "A paragraph over two lines, where 1 < 2.",
        "Made by impact-rig: impact-rig analyze run.csv --report out/",
    ]
    assert "hr" in page.tags and not page.tags & {"script", "link", "iframe", "object"}
    assert page.meta["generator"].startswith("impact-rig ")


def test_a_page_is_written_as_markdown_and_as_html_beside_it(tmp_path):
    md = write_page(LINES, tmp_path / "run.md")
    assert md == tmp_path / "run.md"
    assert md.read_text(encoding="utf-8") == "\n".join(LINES) + "\n"
    assert (tmp_path / "run.html").read_text(encoding="utf-8") == markdown_to_html(LINES)
