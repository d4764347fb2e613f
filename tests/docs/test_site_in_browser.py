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
# What the PyData theme logs as an error on a reader's first page, before a light or dark
# mode is stored: it then takes the automatic mode. Nothing failed to load.
THEME_FIRST_VISIT = "Got invalid theme mode: . Resetting to auto."

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


def site_problems(site: Path, profile: Path) -> list[str]:
    """Every page of ``site`` opened in headless Chromium: its console errors, the images it
    does not show, and its broken links inside the site."""
    html = [page for page in sorted(site.rglob("*.html")) if "_static" not in page.parts]
    visited: dict[Path, dict] = {}
    problems = []
    with headless_chromium(profile) as browser:
        for page in html:
            browser.get(page.as_uri())
            name = page.relative_to(site)
            visited[page] = browser.execute_script(REFERENCES)
            visited[page]["ids"] = set(visited[page]["ids"])
            problems += [f"{name}: console: {error}" for error in console_errors(browser)
                         if THEME_FIRST_VISIT not in error]
            problems += [f"{name}: image not shown: {image['src']}" for image in images(browser)
                         if not (image["complete"] and image["naturalWidth"] > 0)]
    return problems + broken_links(visited, site)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_every_page_of_the_site_loads_with_its_images_and_links(tmp_path):
    site = built_site()
    pages = [page for page in site.rglob("*.html") if "_static" not in page.parts]
    assert len(pages) > 20, f"{site}: only {len(pages)} pages"
    problems = site_problems(site, tmp_path / "profile")
    assert problems == [], f"{len(problems)} problems:\n" + "\n".join(problems[:50])


def test_a_missing_image_file_or_fragment_in_a_small_site_is_found(tmp_path):
    site = tmp_path / "site"
    (site / "docs").mkdir(parents=True)
    png = Path(__file__).resolve().parents[2] / "docs" / "figures" / "demo_bifurcation.png"
    (site / "docs" / "fig.png").write_bytes(png.read_bytes())
    (site / "docs" / "index.html").write_text(
        '<!DOCTYPE html><title>i</title><h1 id="top">i</h1><img src="fig.png">'
        '<img src="gone.png"><a href="other.html#top">ok</a><a href="other.html#nowhere">x</a>'
        '<a href="../missing.html">y</a><a href="https://example.org/">web</a>',
        encoding="utf-8",
    )
    (site / "docs" / "other.html").write_text(
        '<!DOCTYPE html><title>o</title><p id="top"><a href="index.html#top">back</a>',
        encoding="utf-8",
    )
    problems = site_problems(site, tmp_path / "profile")
    assert [problem.split(": ")[0] for problem in problems] == ["docs/index.html"] * 4
    assert "image not shown: gone.png" in " ".join(problems)
    assert sum("gone.png" in problem for problem in problems) == 2  # the console's failed load
    assert any(problem.endswith("other.html#nowhere (no element #nowhere)") for problem in problems)
    assert any(problem.endswith("missing.html (no such file)") for problem in problems)


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
