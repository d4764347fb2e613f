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
from importlib.metadata import entry_points

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
    subparsers = parser.add_subparsers(title="commands", dest="command", metavar="COMMAND")
    for entry in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        try:
            register = entry.load()
        except ImportError as error:  # e.g. Qt libraries missing on a headless PC
            _register_unavailable(subparsers, entry.name, error)
            continue
        register(subparsers)
    return parser


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
    try:
        return int(args.func(args) or 0)
    except CommandError as error:
        print(f"impact-rig {args.command}: error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"impact-rig {args.command}: interrupted", file=sys.stderr)
        return 130


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
