"""The ``impact-rig`` command line: one sub-command per job, contributed by the packages.

Sub-commands are declared as entry points (group ``impact_rig.commands`` in
pyproject.toml); each names a ``register(subparsers)`` function that adds its
parser and sets ``func``.  The dispatcher therefore imports no package statically,
which keeps the layering (only ``gui`` may import Qt) and a fast ``--help``.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from importlib.metadata import PackageNotFoundError, entry_points, version

COMMAND_GROUP = "impact_rig.commands"


class CommandError(Exception):
    """A user-facing failure: printed as one line and exit status 2, no traceback."""


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every installed sub-command registered."""
    parser = argparse.ArgumentParser(
        prog="impact-rig",
        description=(
            "Run, record and explain a laboratory impact oscillator: a pendulum on a "
            "horizontal shake table striking a viscoelastic barrier."
        ),
        epilog="Run 'impact-rig COMMAND --help' for the options of one command.",
    )
    parser.add_argument(
        "--version", action="version", version=f"impact-rig {_installed_version()}"
    )
    subparsers = parser.add_subparsers(title="commands", dest="command", metavar="COMMAND")
    for entry in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        try:
            register = entry.load()
        except ImportError as error:  # e.g. Qt libraries missing on a headless PC
            _register_unavailable(subparsers, entry.name, error)
            continue
        register(subparsers)
    for command in subparsers.choices.values():
        add_common_options(command)
    return parser


def _installed_version() -> str:
    try:
        return version("impact-rig")
    except PackageNotFoundError:
        return "(not installed)"


def add_common_options(parser: argparse.ArgumentParser) -> None:
    """--verbose, --quiet and --operator, which every command takes."""
    group = parser.add_argument_group("every command")
    loudness = group.add_mutually_exclusive_group()
    loudness.add_argument(
        "--verbose", action="store_true", help="log everything, and tracebacks of errors"
    )
    loudness.add_argument("--quiet", action="store_true", help="no progress lines, errors only")
    group.add_argument(
        "--operator",
        default="",
        metavar="NAME",
        help="who ran this, kept in the provenance of every file written "
        "(default: the rig file's rig.operator, if any)",
    )


def add_command(
    subparsers: argparse._SubParsersAction, name: str, summary: str, description: str,
    epilog: str,
) -> argparse.ArgumentParser:
    """A sub-command whose --help shows its description and examples as they are written."""
    return subparsers.add_parser(
        name,
        help=summary,
        description=description,
        epilog=epilog,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def _register_unavailable(subparsers: argparse._SubParsersAction, name: str, error: Exception):
    """Keep the rest of the command line working when one command cannot be imported."""
    reason = f"unavailable on this installation ({error})"
    parser = subparsers.add_parser(name, help=reason, description=reason)

    def fail(args: argparse.Namespace) -> int:
        raise CommandError(reason)

    parser.set_defaults(func=fail)


def main(argv: list[str] | None = None) -> int:
    """Parse the arguments, run the chosen command and return its exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    _stop_on_sigterm()
    if not getattr(args, "func", None):
        parser.print_help()
        return 1
    from analysis.provenance import set_invocation
    from rig import logs

    logs.configure(verbose=args.verbose, quiet=args.quiet)
    set_invocation(["impact-rig", *(sys.argv[1:] if argv is None else argv)], args.operator)
    try:
        return int(args.func(args) or 0)
    except CommandError as error:
        return _fail(args, error, str(error))
    except KeyboardInterrupt:
        print(f"impact-rig {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as error:  # never a traceback for the user; --verbose shows it
        from analysis.output_paths import OutputPathError
        from recording.errors import RecordFormatError

        text = str(error).strip().splitlines()[0] if str(error).strip() else repr(error)
        if not isinstance(error, RecordFormatError | OutputPathError):
            text = f"{type(error).__name__}: {text}"  # unforeseen: say what kind of failure
        return _fail(args, error, text)


def _fail(args: argparse.Namespace, error: BaseException, message: str) -> int:
    """One line naming what was wrong (the traceback too with --verbose); exit status 2."""
    print(f"impact-rig {args.command}: error: {message}", file=sys.stderr)
    if args.verbose:
        import traceback

        traceback.print_exception(error, file=sys.stderr)
    return 2


def _stop_on_sigterm() -> None:
    """Let SIGTERM (kill, systemd, a lab script) stop a command the way Ctrl-C does.

    Every command already turns KeyboardInterrupt into a safe stop: the drive ramped to
    zero and the recording closed with its reason; a bare SIGTERM would skip all that.
    """

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(f"signal {signal.Signals(signum).name}")

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, interrupt)


if __name__ == "__main__":
    # Run as "python -m rig.cli": call the imported module's main, so commands and this
    # dispatcher share one CommandError class (the __main__ copy would not catch theirs).
    from rig.cli import main as installed_main

    sys.exit(installed_main())
