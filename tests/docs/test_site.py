"""The documentation site's configuration (docs/conf.py) stays wired to the pages: CI finds
the build command where the developers' page shows it, warnings as errors, and the site's
navigation holds every page the index links. The build itself runs in CI (.ci/run), not here:
it takes about a minute."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


def site_conf():
    spec = importlib.util.spec_from_file_location("site_conf", DOCS / "conf.py")
    conf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(conf)
    return conf


def test_the_developers_page_keeps_the_site_command_ci_runs():
    lines = (DOCS / "development.md").read_text(encoding="utf-8").splitlines()
    at = lines.index("<!-- docs-command -->")
    assert lines[at + 1].startswith("```")
    command = lines[at + 2].split()
    assert command[-1] == "_site", ".ci/run replaces the output directory '_site'"
    assert {"sphinx-build", "-W", "-n"} <= set(command)


def test_the_navigation_holds_every_page_of_the_index():
    toctrees = site_conf().navigation((DOCS / "index.md").read_text(encoding="utf-8"))
    entries = {line for line in toctrees.splitlines() if line and not line.startswith((":", "`"))}
    pages = {page.stem for page in DOCS.glob("*.md") if page.name != "index.md"}
    assert pages | {"../README", "../CHANGELOG"} == entries
    assert ":caption: Using the rig" in toctrees


def test_the_navigation_takes_the_page_a_list_item_starts_with(tmp_path):
    index = (
        "Start with the [README](../README.md).\n\n## Pages\n\n"
        "- [Guide](guide.md#the-demo): see also [maps](maps.md) and [a file](../x.toml).\n"
        "- The rig file: [`x.toml`](../x.toml).\n"
        "- [Maps](maps.md)\n"
    )
    toctrees = site_conf().navigation(index)
    assert toctrees.split("```{toctree}")[1:] == [
        "\n:hidden:\n\n../README\n```\n\n",
        "\n:hidden:\n:caption: Pages\n\nguide\nmaps\n```\n",
    ]
