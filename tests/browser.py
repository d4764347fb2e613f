"""Headless Chromium driven by selenium, to open the pages the software writes as a reader
does.  Debian's ``chromium`` and ``chromium-driver`` packages (``.ci/run`` installs them);
without them the test is skipped, saying so.  Nothing is downloaded: the driver and the
browser are named, so Selenium Manager never looks for them."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

# as root, offline, with nothing of a user's profile: no sandbox, no GPU, no network calls
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)


@contextmanager
def headless_chromium(profile: Path, width: int = 1280, height: int = 1000) -> Iterator[Any]:
    """A selenium WebDriver on headless Chromium with its console log kept, its profile in
    the new folder ``profile``; skips the test when Chromium or its driver is missing."""
    browser, driver = shutil.which("chromium"), shutil.which("chromedriver")
    if browser is None or driver is None:
        pytest.skip("headless Chromium needs Debian's chromium and chromium-driver packages "
                    "(apt-get install chromium chromium-driver; .ci/run installs them)")
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium: pip install .[test]")
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for flag in FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={profile}")
    options.add_argument(f"--window-size={width},{height}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    session = webdriver.Chrome(service=webdriver.ChromeService(executable_path=driver),
                               options=options)
    try:
        yield session
    finally:
        session.quit()


def console_errors(session: Any) -> list[str]:
    """The browser console's SEVERE entries since the last call (failed loads among them)."""
    return [entry["message"] for entry in session.get_log("browser")
            if entry["level"] == "SEVERE"]


def images(session: Any) -> list[dict[str, Any]]:
    """Every <img> of the open page: its source, whether it finished loading, its pixel width."""
    return session.execute_script(
        "return Array.from(document.images).map(i => "
        "({src: i.getAttribute('src'), complete: i.complete, naturalWidth: i.naturalWidth}));"
    )


def external_references(session: Any) -> list[str]:
    """Every src or href of the open page that leaves the page's own folder for the network."""
    return session.execute_script(
        "return Array.from(document.querySelectorAll('[src], [href]'))"
        ".map(e => e.getAttribute('src') || e.getAttribute('href'))"
        ".filter(u => /^[a-z]+:/i.test(u) || u.startsWith('//'));"
    )
