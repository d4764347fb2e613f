"""Every command shown in a code block of README.md or docs/ runs as the reader would type it:
a renamed command or option, or a command that no longer does what the page says, breaks this
test, not the reader.

The commands are the ``impact-rig ...`` and ``python ...`` lines of the pages' fenced and
indented code blocks (continuation lines joined, comments and what precedes ``&&``, the
installation, left out). Each page's commands run in order in one folder of their own, as a
reader works through the page, in this process (``rig.cli.main``) so that they share its
compiled physics; each must exit with status 0 and write the files its ``--out``, ``--json``
and ``--report`` name. Hardware is the virtual rig: its DAQ board on a pseudo-terminal, its
amplifier on Modbus TCP on 127.0.0.1.

A code block may be preceded by a marker the test reads, an HTML comment (not shown on the
page)::

    <!-- example: record --sim --duration 3; sweep --sim --steps 2 -->

runs the block's ``record`` commands with ``--sim --duration 3`` and its ``sweep`` commands
with ``--sim --steps 2``: an option given replaces the one shown (for ``NAME=VALUE`` values,
the one of the same NAME) or is added. Such shortening uses documented options only, where
the command as shown takes minutes or needs a real rig.

    <!-- example: until ready, then Ctrl-C; sim-rig --port 0 -->

starts each command as a subprocess, waits for the line starting with ``ready`` and stops it
with Ctrl-C (SIGINT), as its page says; it must then exit with status 0.

    <!-- example: run by tests/PATH.py; demo --quick -->

leaves the block's commands to that test, which runs them as shortened (the demo, whose
report tests/demo checks): the test file must exist and name the command and every option
the shortened command uses.

    <!-- example: not run: REASON -->

leaves the block's commands unrun (the desktop application, a Dask cluster of several
machines); every command of every block, run or not, is still parsed by the command-line
parser (``impact-rig``) or checked against its ``--help`` (``python SCRIPT``), as are the
benchmarks' commands on the benchmarks page (from benchmarks/results/), minutes to hours each.

Files a page assumes the reader has (their rig file, someone else's CSV) are made by
``GIVEN`` below, from the shipped rig file, the real records in tests/data or the page's own
earlier recordings.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from markdown_it import MarkdownIt

from harness.results import load_results
from rig.cli import build_parser, main
from tests.suggest.reports import write_report

ROOT = Path(__file__).resolve().parents[2]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
MARKER = re.compile(r"\A<!--\s*example:\s*(.*?)\s*-->\s*\Z", re.S)
OUTPUT_OPTIONS = ("--out", "--json", "--report")
READY_WITHIN_S = 120.0


@dataclass(frozen=True)
class Shown:
    """One command line as a page shows it, and what the marker before its block says."""

    page: Path
    line: int  # 1-based, where the command starts
    command: str
    marker: str = ""

    @property
    def where(self) -> str:
        page = str(self.page.relative_to(ROOT))
        return f"{page}:{self.line}" if self.line else f"{page} ({self.marker})"

    @property
    def argv(self) -> list[str]:
        return shlex.split(self.command)


def _command_lines(content: str, first_line: int) -> list[tuple[int, str]]:
    """A code block's lines with a continuation (trailing backslash) joined, each with the
    1-based page line it starts on."""
    joined: list[tuple[int, str]] = []
    pending, start = "", first_line
    for offset, line in enumerate(content.splitlines()):
        if not pending:
            start = first_line + offset
        if line.rstrip().endswith("\\"):
            pending += line.rstrip()[:-1] + " "
            continue
        joined.append((start, pending + line))
        pending = ""
    return joined


def shown_commands(page: Path) -> list[Shown]:
    """The ``impact-rig ...`` and ``python ...`` command lines of a page's code blocks, with
    the line each starts on and the ``<!-- example: ... -->`` marker right before its block."""
    text = page.read_text(encoding="utf-8")
    shown, marker = [], ""
    for token in MarkdownIt("commonmark").parse(text):
        if token.type == "html_block":
            found = MARKER.match(token.content.strip())
            marker = " ".join(found.group(1).split()) if found else marker  # CI's markers too
            continue
        if token.type in ("fence", "code_block") and token.map:
            first = token.map[0] + (2 if token.type == "fence" else 1)
            for line, content in _command_lines(token.content, first):
                for part in content.split("&&"):
                    if part.strip().startswith(("impact-rig ", "python ")):
                        words = shlex.split(part, comments=True)
                        shown.append(Shown(page, line, shlex.join(words), marker))
        if token.type not in ("paragraph_open", "inline", "paragraph_close"):
            marker = ""
    return shown


SHOWN = [command for page in PAGES for command in shown_commands(page)]


# -- what a marker asks ----------------------------------------------------------------------


@dataclass(frozen=True)
class Plan:
    """How a shown command is run: not at all (with the reason), to its end, or until ready."""

    not_run: str = ""
    run_by: str = ""  # the test file that runs these commands
    until_ready: bool = False
    # the options to set, after the words a command starts with (``record``, ``map basins``)
    options: list[tuple[tuple[str, ...], list[str]]] = field(default_factory=list)


def plan(marker: str) -> Plan:
    """The plan a marker's text states; a marker that says nothing this test reads fails."""
    if not marker:
        return Plan()
    if marker.startswith("not run:"):
        reason = marker.removeprefix("not run:").strip()
        assert reason, f"'example: not run:' needs its reason: {marker!r}"
        return Plan(not_run=reason)
    until_ready, run_by, options = False, "", []
    for clause in filter(None, (c.strip() for c in marker.split(";"))):
        if clause == "until ready, then Ctrl-C":
            until_ready = True
            continue
        if clause.startswith("run by "):
            run_by = clause.removeprefix("run by ")
            continue
        words = shlex.split(clause)
        first = next((at for at, word in enumerate(words) if word.startswith("--")), len(words))
        assert 0 < first < len(words), f"marker clause {clause!r}: COMMAND --OPTION"
        options.append((tuple(words[:first]), words[first:]))
    return Plan(run_by=run_by, until_ready=until_ready, options=options)


def with_options(argv: list[str], options: list[str]) -> list[str]:
    """``argv`` with each of ``options`` set: ``--name VALUE`` replaces the value shown for
    ``--name`` (of a ``NAME=VALUE`` value, the one with the same NAME), or is added; a flag is
    added unless it is there."""
    argv, at = list(argv), 0
    while at < len(options):
        name = options[at]
        given = at + 1 < len(options) and not options[at + 1].startswith("--")
        value = options[at + 1] if given else None
        at += 1 if value is None else 2
        if value is None:
            argv += [] if name in argv else [name]
            continue
        key = value.partition("=")[0] + "=" if "=" in value else ""
        for where in range(len(argv) - 1):
            if argv[where] == name and argv[where + 1].startswith(key):
                argv[where + 1] = value
                break
        else:
            argv += [name, value]
    return argv


def to_run(shown: Shown) -> list[str]:
    """The argument list the test runs for a shown command (its marker's options applied)."""
    argv = shown.argv
    for command, options in plan(shown.marker).options:
        if tuple(argv[1 : 1 + len(command)]) == command:
            argv = with_options(argv, options)
    return argv


def test_with_options_replaces_what_is_shown_and_adds_the_rest():
    shown = ["impact-rig", "map", "regimes", "--vary", "a=0:1:100", "--vary", "b=0:1:100",
             "--ics", "2", "--out", "x.h5"]
    assert with_options(shown, ["--vary", "b=0:1:3", "--ics", "1", "--workers", "1", "--sim"]) == [
        "impact-rig", "map", "regimes", "--vary", "a=0:1:100", "--vary", "b=0:1:3",
        "--ics", "1", "--out", "x.h5", "--workers", "1", "--sim"]


def test_a_marker_states_a_plan_or_fails():
    assert plan("not run: the desktop application").not_run == "the desktop application"
    both = plan("until ready, then Ctrl-C; sim-rig --port 0; map basins --ics 1")
    assert both.until_ready
    assert both.options == [(("sim-rig",), ["--port", "0"]), (("map", "basins"), ["--ics", "1"])]
    with pytest.raises(AssertionError, match="needs its reason"):
        plan("not run:")
    with pytest.raises(AssertionError, match="COMMAND --OPTION"):
        plan("shorter please")


def test_commands_and_their_markers_are_found_with_their_lines(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "# A page\n\n<!-- example: record --sim -->\n```\npip install . && impact-rig record \\\n"
        "    --out a.h5   # a comment\nls\n```\n\n    impact-rig demo --quick\n",
        encoding="utf-8",
    )
    assert shown_commands(page) == [
        Shown(page, 5, "impact-rig record --out a.h5", "record --sim"),
        Shown(page, 10, "impact-rig demo --quick", ""),
    ]


def test_the_pages_show_commands_and_most_are_run():
    assert len(SHOWN) > 20
    assert any(shown.command == "impact-rig demo" for shown in SHOWN)
    not_run = [shown for shown in SHOWN if plan(shown.marker).not_run or plan(shown.marker).run_by]
    assert len(not_run) < len(SHOWN) / 3, [shown.where for shown in not_run]


# -- every command is accepted by its parser -------------------------------------------------


def rejection(parser, argv: list[str]) -> str | None:
    """None when the parser accepts ``argv`` (without the program's name), else its error."""
    errors = io.StringIO()
    try:
        with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
            parser.parse_args(argv)
    except SystemExit as stop:
        if stop.code:
            return errors.getvalue().strip().splitlines()[-1]
    return None


@pytest.fixture(scope="module")
def parser():
    return build_parser()


IMPACT_RIG = [shown for shown in SHOWN if shown.argv[0] == "impact-rig"]
# The benchmarks' commands, shown on the benchmarks page (generated from their results):
# minutes to hours each, so not run here; their options are checked against --help.
BENCHMARK_PAGE = ROOT / "docs" / "benchmarks.md"
BENCHMARKS = [
    Shown(BENCHMARK_PAGE, 0, shlex.join(words[words.index("python"):]),
          f"not run: benchmarks/results/{key}.json")
    for key, outcome in load_results().items()
    if "python" in (words := shlex.split(outcome["command"]))
]
PYTHON = [shown for shown in [*SHOWN, *BENCHMARKS] if shown.argv[0] == "python"]
SCRIPTS = sorted({shown.argv[1] for shown in PYTHON})


@pytest.mark.parametrize("shown", IMPACT_RIG, ids=lambda shown: f"{shown.where}")
def test_a_shown_command_and_the_one_run_are_accepted_by_the_parser(parser, shown):
    shown_error, run_error = rejection(parser, shown.argv[1:]), rejection(parser, to_run(shown)[1:])
    assert shown_error is None, f"{shown.where}: {shown_error}"
    assert run_error is None, f"{shown.where} as run: {run_error}"


@pytest.mark.parametrize("script", SCRIPTS)
def test_a_shown_python_script_takes_the_options_it_is_shown_with(script):
    shown = [command for command in PYTHON if command.argv[1] == script]
    where = ", ".join(command.where for command in shown)
    assert (ROOT / script).is_file(), f"{where}: no script {script}"
    options = {word.partition("=")[0] for command in shown for word in command.argv[2:]
               if word.startswith("--")}
    if not options:  # a script without options may not take --help either: nothing to check
        return
    done = subprocess.run([sys.executable, script, "--help"], cwd=ROOT, capture_output=True,
                          text=True, timeout=120, check=False, env=_env())
    assert done.returncode == 0, f"{where}: {script} --help failed: {done.stderr[-500:]}"
    unknown = sorted(option for option in options
                     if not re.search(rf"(?<![\w-]){re.escape(option)}(?![\w-])", done.stdout))
    assert unknown == [], f"{where}: {script} --help does not list {unknown}"


def test_a_renamed_option_is_rejected(parser):
    assert rejection(parser, ["demo", "--quick"]) is None
    assert "unrecognized arguments: --quik" in rejection(parser, ["demo", "--quik"])


# -- every command is run --------------------------------------------------------------------


def _env() -> dict[str, str]:
    paths = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    return {**os.environ, "PYTHONPATH": paths, "QT_QPA_PLATFORM": "offscreen"}


def _copy_pair(source: Path, csv_name: str, json_name: str) -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        shutil.copyfile(source, folder / csv_name)
        shutil.copyfile(source.with_suffix(".json"), folder / json_name)
    return make


def _rig_file(replace: tuple[str, str] = ("", "")) -> Callable[[Path], None]:
    def make(folder: Path) -> None:
        text = (ROOT / "rig" / "default_rig.toml").read_text(encoding="utf-8")
        name = "lab.toml" if not replace[0] else "scpi_rig.toml"
        (folder / name).write_text(text.replace(*replace) if replace[0] else text, encoding="utf-8")
    return make


def _exported(
    recording: str, csv_name: str, json_name: str, *, step: bool = False
) -> Callable[[Path], None]:
    """An exchange CSV made from one of the page's own recordings (the first sweep step)."""
    def make(folder: Path) -> None:
        scratch = folder / f"_given_{csv_name}"
        scratch.mkdir()
        argv = ["export", str(folder / recording), "--out", str(scratch / "x.csv"), "--quiet"]
        assert main(argv + (["--per-step"] if step else [])) == 0, f"exporting {recording} failed"
        made = scratch / ("x_step00.csv" if step else "x.csv")
        _copy_pair(made, csv_name, json_name)(folder)
    return make


REAL_DECAY = ROOT / "tests" / "data" / "real_exchange" / "uw_single_small_decay.csv"
SCPI_SHAKER = ('kind = "modbus"\n', 'kind = "scpi"\nresource = "sim"\ngain_m_per_v = 2e-3\n')
# The files a page's commands take as given, each made when a command names it and it is
# not there yet: the reader's own rig file (here the shipped virtual rig), a decay recorded
# elsewhere (a real one), a sweep step and an impact decay as exchange CSV, and a forced
# record's analysis report with two competing explanations (tests/suggest/reports.py).
GIVEN: dict[str, Callable[[Path], None]] = {
    "lab.toml": _rig_file(),
    "scpi_rig.toml": _rig_file(SCPI_SHAKER),
    "their_decay.csv": _copy_pair(REAL_DECAY, "their_decay.csv", "their_decay.json"),
    "their_impacts.csv": _exported("impacts.h5", "their_impacts.csv", "impacts.json"),
    "sweep_step.csv": _exported("sweep.h5", "sweep_step.csv", "sweep_step.json", step=True),
    "run.report.json": lambda folder: write_report(folder / "run.report.json"),
}


def _outputs(argv: list[str]) -> list[str]:
    return [argv[at + 1] for at, word in enumerate(argv[:-1])
            if word in OUTPUT_OPTIONS and argv[at + 1] != "-"]


def _written(folder: Path, name: str) -> bool:
    """The file or folder exists, or, for per-step and per-segment output, NAME_*."""
    path = folder / name
    return path.exists() or any(path.parent.glob(f"{path.stem}_*{path.suffix}"))


def _run_until_ready(argv: list[str], folder: Path) -> str | None:
    """Start the command, wait for its ``ready`` line, Ctrl-C it: None, or what went wrong."""
    process = subprocess.Popen([sys.executable, "-m", "rig.cli", *argv[1:]], cwd=folder,
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True, env=_env())
    lines: list[str] = []
    try:
        deadline = time.monotonic() + READY_WITHIN_S
        while time.monotonic() < deadline:
            line = process.stdout.readline()
            if not line:
                break
            lines.append(line)
            if line.startswith("ready"):
                process.send_signal(signal.SIGINT)
                output, _ = process.communicate(timeout=60)
                lines.append(output)
                return None if process.returncode == 0 else (
                    f"exited {process.returncode} after Ctrl-C: {''.join(lines)[-400:]}")
        return f"no 'ready' line: {''.join(lines)[-400:]}"
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()


def _run(shown: Shown, folder: Path, capsys) -> str | None:
    """Run one shown command in ``folder``: None, or what went wrong."""
    argv = to_run(shown)
    for word in argv:
        if word in GIVEN and not (folder / word).exists():
            GIVEN[word](folder)
    if plan(shown.marker).until_ready:
        return _run_until_ready(argv, folder)
    if argv[0] == "python":
        done = subprocess.run([sys.executable, str(ROOT / argv[1]), *argv[2:]], cwd=folder,
                              capture_output=True, text=True, timeout=600, check=False, env=_env())
        status, said = done.returncode, done.stdout + done.stderr
    else:
        capsys.readouterr()
        status = main(argv[1:])
        said = "".join(capsys.readouterr())
    if status != 0:
        return f"exited {status}: {said.strip()[-600:]}"
    missing = [name for name in _outputs(argv) if not _written(folder, name)]
    return f"did not write {missing}" if missing else None


def _runs_here(shown: Shown) -> bool:
    return not (plan(shown.marker).not_run or plan(shown.marker).run_by)


RUN_BY = [shown for shown in SHOWN if plan(shown.marker).run_by]


@pytest.mark.parametrize("shown", RUN_BY, ids=lambda shown: f"{shown.where}")
def test_a_command_run_by_another_test_is_run_there_as_shortened(shown):
    runner = ROOT / plan(shown.marker).run_by
    assert runner.is_file(), f"{shown.where}: no test {plan(shown.marker).run_by}"
    text = runner.read_text(encoding="utf-8")
    words = [word for word in to_run(shown)[1:] if word.startswith("--") and word != "--out"]
    missing = [word for word in [to_run(shown)[1], *words] if f'"{word}"' not in text]
    assert missing == [], f"{shown.where}: {runner.name} does not run it with {missing}"


RUN_PAGES = sorted({shown.page for shown in SHOWN if _runs_here(shown)})


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("page", RUN_PAGES, ids=lambda page: str(page.relative_to(ROOT)))
def test_every_command_a_page_shows_runs(page, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    done: dict[str, str | None] = {}
    failures = []
    for shown in shown_commands(page):
        if not _runs_here(shown):
            continue
        argv = shlex.join(to_run(shown))
        if argv not in done:  # a page showing the same command twice runs it once
            started = time.perf_counter()
            done[argv] = _run(shown, tmp_path, capsys)
            with capsys.disabled():
                print(f"\n{shown.where}: {time.perf_counter() - started:.1f} s  {argv}")
        if done[argv] is not None:
            failures.append(f"{shown.where}: `{shown.command}` (run as `{argv}`) {done[argv]}")
    assert failures == [], "\n".join(failures)
