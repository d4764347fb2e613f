"""Sphinx configuration of the documentation site: the Markdown pages of docs/, README.md and
CHANGELOG.md read by MyST, and the API reference generated from the docstrings.

The source directory is the repository's root (``sphinx-build -c docs . _site``), restricted to
those pages by ``include_patterns``: the pages link each other, the README and the shipped rig
file as they do on GitHub (``../README.md``), and those links resolve the same way here.
"""

from __future__ import annotations

import ast
import builtins
import functools
import importlib
import inspect
import re
import sys
from pathlib import Path

from markdown_it import MarkdownIt

# The packages documented are the ones beside this file, not whichever copy is installed.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

project = "impact-rig"
author = "the impact-rig authors"
copyright = "the impact-rig authors"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
]

root_doc = "docs/index"
# Pages kept beside what they describe and linked from the docs: in the site, reachable by
# those links only (orphans, outside the navigation).
PAGES_ELSEWHERE = ["tests/data/real_exchange/SOURCE.md"]  # the real records' sources, licences
include_patterns = ["README.md", "CHANGELOG.md", "docs/**", *PAGES_ELSEWHERE]
exclude_patterns = ["docs/_templates/**"]

# Every reference must resolve: a link to a page or heading that is not there, or a
# docstring's :func:/:class: to a name of ours that is not documented, fails the build.
nitpicky = True
# References to other projects' objects (numpy, scipy, h5py, Qt, the standard library) are
# shown as plain text by resolve_reference below: no inventory is fetched, so the build never
# depends on another site being reachable.
OUR_PACKAGES = ("analysis", "drivers", "hardware_sim", "rig", "gui")
# A private base class, named by "Bases:" under a public class: private names are not part
# of the reference.
nitpick_ignore_regex = [(r"py:class", r".*\._[A-Za-z]\w*")]
# Type variables of generic protocols: named in signatures, nothing to link to.
nitpick_ignore = [
    ("py:class", "analysis.discrepancy.forced_models.Fit"),
    ("py:obj", "analysis.discrepancy.forced_models.Fit"),
    ("py:class", "analysis.discrepancy.forward.Fitted"),
    ("py:obj", "analysis.discrepancy.forward.Fitted"),
]

myst_heading_anchors = 4  # links to a section, as GitHub writes them (guide.md#the-demo)

autosummary_generate = True
# Each object is documented once, in the module that defines it: a package's re-exports
# (its __all__) are not documented again under the package's name.
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"

html_theme = "pydata_sphinx_theme"
html_title = "impact-rig"
templates_path = ["_templates"]
# The pages' sidebar lists every page by section (docs/_templates/site-nav.html); the API
# reference's, the theme's own, its modules.
html_sidebars = {
    **{pages: ["site-nav"] for pages in ("README", "CHANGELOG", "docs/*")},
    "docs/api/**": ["sidebar-nav-bs"],
}
html_theme_options = {
    "navbar_center": [],  # the sections are in the sidebar; the header keeps search
    "navigation_with_keys": False,
    "show_toc_level": 2,
}
html_show_sourcelink = False


def navigation(index_text: str) -> str:
    """Hidden toctrees built from docs/index.md's own links: the pages linked before its first
    section, then under each ``##`` section the page each list item starts with, captioned by
    the section's title. Adding a page to the index adds it to the site's navigation."""
    groups: list[tuple[str, list[str]]] = [("", [])]
    tokens = MarkdownIt("commonmark").parse(index_text)
    item_start = False
    for at, token in enumerate(tokens):
        if token.type == "heading_open" and token.tag == "h2":
            groups.append((tokens[at + 1].content, []))
        elif token.type == "list_item_open":
            item_start = True
        elif token.type == "inline":
            links = [c.attrGet("href") for c in token.children or () if c.type == "link_open"]
            if len(groups) > 1:
                links = links[:1] if item_start else []
            item_start = False
            for href in links:
                page = re.sub(r"#.*$", "", str(href))
                if page.endswith(".md") and "://" not in page:
                    groups[-1][1].append(page.removesuffix(".md"))
    blocks = []
    for caption, pages in groups:
        if pages:
            options = ":hidden:\n" + (f":caption: {caption}\n" if caption else "")
            blocks.append("```{toctree}\n" + options + "\n" + "\n".join(pages) + "\n```\n")
    return "\n" + "\n".join(blocks)


def add_navigation(app, docname: str, source: list[str]) -> None:
    if docname == root_doc:
        source[0] += navigation(source[0])
    elif f"{docname}.md" in PAGES_ELSEWHERE:
        source[0] = "---\norphan: true\n---\n" + source[0]


@functools.cache
def hinted_imports(module) -> dict[str, str]:
    """The names a module imports for its type hints only (under ``if TYPE_CHECKING:``), each
    with the dotted path it stands for."""
    names = {}
    for node in ast.walk(ast.parse(inspect.getsource(module))):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for statement in node.body:
                if isinstance(statement, ast.ImportFrom) and statement.level == 0:
                    for alias in statement.names:
                        names[alias.asname or alias.name] = f"{statement.module}.{alias.name}"
    return names


def dotted_object(path: str):
    """The object an importable dotted path names, or None."""
    parts = path.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            found = importlib.import_module(".".join(parts[:cut]))
            for part in parts[cut:]:
                found = getattr(found, part)
            return found
        except (ImportError, AttributeError):
            continue
    return None


@functools.cache
def named_object(target: str, module_name: str | None):
    """What a reference's dotted name is where it was written: in that module's namespace
    (``np.ndarray``, an imported ``Path``), among its type-hint-only imports, else an
    importable dotted path, else a builtin. None when it names nothing."""
    first, _, rest = target.partition(".")
    if module_name:
        module = importlib.import_module(module_name)
        if hasattr(module, first):
            return dotted_object(f"{module_name}.{target}")
        hinted = hinted_imports(module)
        if first in hinted:
            return dotted_object(".".join(filter(None, [hinted[first], rest])))
    found = dotted_object(target)
    if found is None and not rest:
        found = getattr(builtins, target, None)
    return found


def resolve_reference(app, env, node, contnode):
    """A Python reference Sphinx could not resolve. A name of another project's (numpy, Qt,
    the standard library) is shown as text; a name a package of ours re-exports
    (``analysis.simulate.simulate``, as users import it) resolves to where it is defined and
    documented; anything else stays unresolved, and the build fails on it."""
    if node.get("refdomain") != "py":
        return None
    try:
        found = named_object(node["reftarget"], node.get("py:module"))
    except ImportError:
        return None
    if found is None:
        return None
    owner = getattr(found, "__module__", None) or getattr(found, "__name__", "")
    if str(owner).partition(".")[0] not in OUR_PACKAGES:
        return contnode
    if not hasattr(found, "__qualname__"):  # ours, and not a documented function or class
        return None
    defined = f"{found.__module__}.{found.__qualname__}"
    if defined == node["reftarget"]:
        return None
    return env.domains["py"].resolve_xref(
        env, node["refdoc"], app.builder, node["reftype"], defined, node, contnode
    )


def parseable_signature(app, what, name, obj, options, signature, return_annotation):
    """A default shown by its repr where that is not Python (a dataclass field's default
    factory, ``<factory>``; ``<built-in function monotonic>``) makes Sphinx split the
    signature at every comma and name pieces such as ``dict[str`` as references: such a
    default is shown as ``...``."""
    if signature and "<" in signature:
        return re.sub(r"(=\s*)<[^<>]*>", r"\1...", signature), return_annotation
    return None


def redirect_to_index(app, exception) -> None:
    """The site's root opens the documentation index."""
    if exception is None and app.builder.format == "html":
        target = app.builder.get_target_uri(root_doc)
        Path(app.outdir, "index.html").write_text(
            f'<!DOCTYPE html>\n<meta http-equiv="refresh" content="0; url={target}">\n'
            f'<a href="{target}">impact-rig documentation</a>\n',
            encoding="utf-8",
        )


def setup(app) -> None:
    app.connect("source-read", add_navigation)
    app.connect("autodoc-process-signature", parseable_signature)
    app.connect("missing-reference", resolve_reference)
    app.connect("build-finished", redirect_to_index)
