"""The command line under generated arguments: every ``impact-rig`` sub-command, options
and values drawn from its own parser.

Each generated command line runs ``rig.cli.main`` in a forked child (its own session, in a
scratch folder, stdin empty) and is judged by :func:`check_command_line`: it ends within
``SLOW_S`` with exit status 0, or with one line ``impact-rig CMD: error: ...`` naming
what was wrong and no traceback; an error the program did not foresee (``main`` then
names the exception's type, ``error: ValueError: ...``) is a bad answer too.  A command
line still running after ``SLOW_S`` without an error was accepted and is doing its work
(an analysis, a recording, the virtual rig serving until Ctrl-C): it is killed and
counted (:data:`WORKING`), not judged.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import shutil
import signal
import sys
import time
from pathlib import Path

from hypothesis import strategies as st

from harness.fuzz.boundaries import SLOW_S, BadAnswerError, write_small_recording

ROOT = Path(__file__).resolve().parents[2]
EXCHANGE_CSV = ROOT / "tests" / "data" / "real_exchange"
WORKING = "working"  # the answer of a command line accepted and still at work after SLOW_S
NEVER = {"--verbose", "-h", "--help", "--version"}  # tracebacks and help by design
UNFORESEEN = re.compile(r": error: [A-Z][A-Za-z]*(Error|Exception|Warning)\b")


def commands() -> dict[str, argparse.ArgumentParser]:
    """Every sub-command's parser, by name."""
    from rig.cli import build_parser

    parser = build_parser()
    (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sorted(sub.choices.items()))


_ORIGINALS: dict[Path, bytes] = {}  # the input files' bytes, put back after every run


def inputs(folder: Path) -> list[str]:
    """Files a generated command line may name: real inputs, and things that are not.

    The real ones are copies in ``folder/inputs`` (a command line may well write over
    one with ``--overwrite``: :func:`check_command_line` puts them back after each run),
    never the repository's own files.
    """
    copies = folder / "inputs"
    copies.mkdir(exist_ok=True)
    recording = copies / "small.h5"
    if not recording.exists():
        write_small_recording(recording)
    sources = [
        *sorted(EXCHANGE_CSV.glob("rotary_free_swing_1.*")),
        ROOT / "rig" / "default_rig.toml",
        ROOT / "README.md",
    ]
    for source in sources:
        (copies / source.name).write_bytes(source.read_bytes())
    for path in copies.iterdir():
        _ORIGINALS[path] = path.read_bytes()
    return [
        str(recording),
        str(copies / "rotary_free_swing_1.csv"),
        str(copies / "default_rig.toml"),
        str(copies / "README.md"),
        str(copies / "missing.h5"),
        str(copies),
        "/dev/null",
    ]


def _put_back_inputs() -> None:
    for path, data in _ORIGINALS.items():
        if not path.is_file() or path.read_bytes() != data:
            if path.is_dir():
                shutil.rmtree(path)
            path.write_bytes(data)
    for path in {p.parent for p in _ORIGINALS}:
        for extra in path.iterdir():  # written beside them: gone again
            if extra not in _ORIGINALS:
                if extra.is_dir():
                    shutil.rmtree(extra)
                else:
                    extra.unlink()


def value_text(files: list[str]) -> st.SearchStrategy[str]:
    """An option's value as a user might type it, or mistype it."""
    return st.one_of(
        st.sampled_from(["0", "1", "-1", "0.5", "2", "3", "10", "0.01", "1e-3", "100"]),
        st.sampled_from(["1e308", "1e400", "nan", "inf", "-inf", "1e-300", "-0", "0x10"]),
        st.sampled_from(["", " ", "abc", "\u00e9", "1,5", "a=1", "x=nan", "--", "-", "3:4"]),
        st.sampled_from(files),
        st.sampled_from(["out.h5", "out.csv", "out.json", "out/", "report", "sub/out.h5"]),
        st.floats(allow_nan=True, allow_infinity=True).map(repr),
        st.integers(-(2**40), 2**40).map(str),
        st.text(max_size=6),
    )


@st.composite
def command_lines(draw: st.DrawFn, name: str, files: list[str]) -> list[str]:
    """One command line for the sub-command ``name``: positionals and options drawn from its
    parser (choices mostly from its choices), values from :func:`value_text`."""
    parser = commands()[name]
    argv = [name]
    values = value_text(files)
    for action in parser._actions:
        if action.option_strings or action.nargs == 0:
            continue
        if draw(st.integers(0, 9)) > 0:  # positionals: mostly given
            argv.append(draw(_value(action, values)))
    options = [
        a for a in parser._actions if a.option_strings and not NEVER & set(a.option_strings)
    ]
    for action in draw(st.lists(st.sampled_from(options), max_size=6)) if options else []:
        argv.append(draw(st.sampled_from(action.option_strings)))
        if action.nargs == 0:
            continue
        count = 1 if action.nargs in (None, "?") else draw(st.integers(1, 3))
        argv += [draw(_value(action, values)) for _ in range(count)]
    if draw(st.integers(0, 19)) == 0:
        argv.insert(draw(st.integers(1, len(argv))), draw(st.sampled_from(["--bogus", "-z"])))
    return argv


def _value(action: argparse.Action, values: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
    if action.choices:
        return st.one_of(st.sampled_from([str(c) for c in action.choices]), values)
    return values


def run_command_line(argv: list[str], folder: Path) -> tuple[int | None, str, str, float]:
    """Run ``impact-rig ARGV`` in a forked child in ``folder``: (exit status, or None when
    still running after SLOW_S and killed; stdout; stderr; seconds)."""
    out_path, err_path = folder / ".stdout", folder / ".stderr"
    started = time.perf_counter()
    pid = os.fork()
    if pid == 0:  # the child: never returns
        code = 70
        try:
            os.setsid()
            os.chdir(folder)
            os.environ["QT_QPA_PLATFORM"] = "offscreen"  # `impact-rig gui` needs no display
            null = os.open(os.devnull, os.O_RDONLY)
            os.dup2(null, 0)
            sys.stdin = io.TextIOWrapper(io.FileIO(0, "r", closefd=False))
            sys.stdout = open(out_path, "w", encoding="utf-8")  # noqa: SIM115
            sys.stderr = open(err_path, "w", encoding="utf-8")  # noqa: SIM115
            from rig.cli import main

            try:
                code = main(argv)
            except SystemExit as leaving:  # argparse: 2 after its usage and error lines
                code = leaving.code if isinstance(leaving.code, int) else 1
        except BaseException:  # written out as the traceback it is
            import traceback

            traceback.print_exc(file=sys.stderr)
            code = 70
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    code: int | None = None
    deadline = time.monotonic() + SLOW_S
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            code = os.waitstatus_to_exitcode(status)
            break
        if time.monotonic() > deadline:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            break
        time.sleep(0.005)
    took = time.perf_counter() - started
    read = lambda p: p.read_text(encoding="utf-8", errors="replace") if p.exists() else ""  # noqa: E731
    return code, read(out_path), read(err_path), took


def check_command_line(argv: list[str], folder: Path) -> str:
    """Run one command line and judge its answer (BadAnswerError); returns "ok", "refused"
    or WORKING."""
    try:
        code, _out, err, _took = run_command_line(argv, folder)
    finally:
        _put_back_inputs()
    shown = " ".join(repr(a) if not a or " " in a else a for a in argv)
    if "Traceback" in err:
        raise BadAnswerError(f"impact-rig {shown}: a traceback: {err.strip().splitlines()[-1]}")
    errors = [line for line in err.splitlines() if ": error:" in line]
    if code is None:
        if errors:
            raise BadAnswerError(f"impact-rig {shown}: said {errors[0]!r} but did not end")
        return WORKING
    if code == 0:
        return "ok"
    if code < 0:
        raise BadAnswerError(f"impact-rig {shown}: ended by signal {-code}")
    if len(errors) != 1:
        raise BadAnswerError(f"impact-rig {shown}: exit {code} with {len(errors)} error lines")
    if UNFORESEEN.search(errors[0]):
        raise BadAnswerError(f"impact-rig {shown}: an error it did not foresee: {errors[0]}")
    return "refused"
