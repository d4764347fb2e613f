"""Every ``impact-rig`` command line shown in a fenced block of README.md or docs/ is still
accepted by the command-line parser: a renamed command or option breaks this test, not the
reader. The commands are parsed, not run."""

from __future__ import annotations

import contextlib
import io
import shlex
from pathlib import Path

import pytest
from markdown_it import MarkdownIt

from rig.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def shown_commands(text: str) -> list[str]:
    """The ``impact-rig ...`` command lines of a page's fenced and indented code blocks,
    continuation lines joined, comments and what precedes ``&&`` left out."""
    commands = []
    for token in MarkdownIt("commonmark").parse(text):
        if token.type not in ("fence", "code_block"):
            continue
        for line in token.content.replace("\\\n", " ").splitlines():
            for part in line.split("&&"):
                if part.strip().startswith("impact-rig "):
                    commands.append(shlex.join(shlex.split(part, comments=True)))
    return commands


def rejection(parser, command: str) -> str | None:
    """None when the parser accepts ``command``, else its error message."""
    errors = io.StringIO()
    try:
        with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
            parser.parse_args(shlex.split(command)[1:])
    except SystemExit as stop:
        if stop.code:
            return errors.getvalue().strip().splitlines()[-1]
    return None


SHOWN = [
    (page, command)
    for page in PAGES
    for command in shown_commands(page.read_text(encoding="utf-8"))
]


def test_the_pages_show_commands():
    assert len(SHOWN) > 20
    assert any(command == "impact-rig demo" for _, command in SHOWN)


@pytest.fixture(scope="module")
def parser():
    return build_parser()


@pytest.mark.parametrize(("page", "command"), SHOWN, ids=[f"{p.name}:{c}" for p, c in SHOWN])
def test_a_shown_command_is_accepted_by_the_parser(parser, page, command):
    assert rejection(parser, command) is None, f"{page.name}: {rejection(parser, command)}"


def test_a_renamed_option_is_rejected(parser):
    assert rejection(parser, "impact-rig demo --quick") is None
    assert "unrecognized arguments: --quik" in rejection(parser, "impact-rig demo --quik")
