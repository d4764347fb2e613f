"""The built documentation site, opened in headless Chromium as a reader opens it: every page
loads with no failed request in the console, every image is shown, and every link inside the
site leads to a file that exists and, with a ``#fragment``, to an element of that page.

The site is the one CI's docs step has just built (``.ci/run``; docs/development.md): building
it takes one to two minutes, too long for the test suite, so this test reads the folder that
``IMPACT_RIG_SITE`` names and is skipped, saying so, without it::

    sphinx-build -n -W --keep-going -c docs . _site
    IMPACT_RIG_SITE=_site pytest tests/docs/test_site_in_browser.py
"""

from __future__ import annotations

import os
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

from tests.browser import console_errors, headless_chromium, images

SITE_VARIABLE = "IMPACT_RIG_SITE"

# Every href and src of the open page, as the browser resolves it (absolute URLs).
REFERENCES = (
    "return {links: Array.from(document.querySelectorAll('a[href]')).map(a => a.href),"
    " ids: Array.from(document.querySelectorAll('[id]')).map(e => e.id)"
    ".concat(Array.from(document.querySelectorAll('a[name]')).map(a => a.name))};"
)


def built_site() -> Path:
    folder = os.environ.get(SITE_VARIABLE)
    if not folder:
        pytest.skip(f"no built site: CI's docs step builds it and sets {SITE_VARIABLE} "
                    "(docs/development.md)")
    site = Path(folder).resolve()
    assert (site / "docs" / "index.html").is_file(), f"{SITE_VARIABLE}={folder}: no docs/index.html"
    return site


def local_target(url: str, site: Path) -> tuple[Path, str] | None:
    """The file inside the site a link leads to and its fragment; None for the web."""
    parts = urlsplit(url)
    if parts.scheme != "file":
        return None
    path = Path(unquote(parts.path))
    if path.is_dir():
        path = path / "index.html"
    return path, unquote(parts.fragment)


def broken_links(pages: dict[Path, dict], site: Path) -> list[str]:
    """Every link of a visited page whose file is missing, leaves the site, or whose
    fragment names no element of the page it leads to."""
    broken = []
    for page, seen in pages.items():
        for url in seen["links"]:
            target = local_target(url, site)
            if target is None:
                continue
            path, fragment = target
            where = f"{page.relative_to(site)}: {url}"
            if not path.is_relative_to(site):
                broken.append(f"{where} (outside the site)")
            elif not path.is_file():
                broken.append(f"{where} (no such file)")
            elif fragment and path in pages and fragment not in pages[path]["ids"]:
                broken.append(f"{where} (no element #{fragment})")
    return broken


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_every_page_of_the_site_loads_with_its_images_and_links(tmp_path):
    site = built_site()
    html = sorted(site.rglob("*.html"))
    html = [page for page in html if "_static" not in page.parts]
    assert len(html) > 20, f"{site}: only {len(html)} pages"
    visited: dict[Path, dict] = {}
    failures = []
    with headless_chromium(tmp_path / "profile") as browser:
        for page in html:
            browser.get(page.as_uri())
            name = page.relative_to(site)
            visited[page] = browser.execute_script(REFERENCES)
            visited[page]["ids"] = set(visited[page]["ids"])
            failures += [f"{name}: console: {error}" for error in console_errors(browser)]
            failures += [f"{name}: image not shown: {image['src']}" for image in images(browser)
                         if not (image["complete"] and image["naturalWidth"] > 0)]
    failures += broken_links(visited, site)
    assert failures == [], f"{len(failures)} problems:\n" + "\n".join(failures[:50])


def test_a_link_to_a_missing_file_or_fragment_is_found(tmp_path):
    site = tmp_path
    page, other = site / "a.html", site / "b.html"
    page.write_text("x")
    other.write_text("x")
    visited = {
        page: {"links": [other.as_uri() + "#there", other.as_uri() + "#gone",
                         (site / "c.html").as_uri(), "https://example.org/x",
                         (site.parent / "out.html").as_uri()], "ids": set()},
        other: {"links": [], "ids": {"there"}},
    }
    assert broken_links(visited, site) == [
        f"a.html: {other.as_uri()}#gone (no element #gone)",
        f"a.html: {(site / 'c.html').as_uri()} (no such file)",
        f"a.html: {(site.parent / 'out.html').as_uri()} (outside the site)",
    ]
