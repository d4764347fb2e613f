"""Logging for the command line: standard ``logging`` on stderr at the level --verbose and
--quiet choose, and a log file beside each recording with everything the run said.

Progress lines are INFO records of the ``impact_rig.progress`` logger: shown by default,
hidden by --quiet, kept in a run's log file.  Other INFO and DEBUG records show with
--verbose only, and so do records logged with ``extra=FILE_ONLY`` (an error the command
then reports on its one line anyway).
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Iterator
from pathlib import Path

LOGGER_NAME = "impact_rig"
CONSOLE_FORMAT = "%(message)s"
FILE_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"

log = logging.getLogger(LOGGER_NAME)
progress_log = logging.getLogger(f"{LOGGER_NAME}.progress")
FILE_ONLY = {"file_only": True}  # extra= of a record meant for the log file, not the console


def progress(text: str) -> None:
    """A progress line: on stderr unless --quiet, and in the run's log file if there is one."""
    progress_log.info("%s", text)


def log_provenance() -> None:
    """The provenance block (analysis.provenance) as the log's first record, so that a log
    file too says which software, versions and command made it."""
    from analysis.json_output import to_json_text
    from analysis.provenance import provenance

    log.info("provenance: %s", to_json_text(provenance(), one_line=True))


def _default_console(record: logging.LogRecord) -> bool:
    """Without --verbose: warnings, errors and progress lines (above the handler's level),
    none meant for the log file only."""
    if getattr(record, "file_only", False):
        return False
    return record.levelno >= logging.WARNING or record.name == progress_log.name


def configure(*, verbose: bool = False, quiet: bool = False) -> None:
    """Send log records to stderr: warnings, errors and progress by default, everything with
    ``verbose`` (and tracebacks), errors only with ``quiet``."""
    level = logging.DEBUG if verbose else logging.ERROR if quiet else logging.INFO
    console = logging.StreamHandler(sys.stderr)
    console.setFormatter(logging.Formatter(CONSOLE_FORMAT))
    console.setLevel(level)
    if not verbose:
        console.addFilter(_default_console)
    root = logging.getLogger()
    for handler in list(root.handlers):
        if getattr(handler, "impact_rig_console", False):
            root.removeHandler(handler)
    console.impact_rig_console = True  # type: ignore[attr-defined]
    root.addHandler(console)
    root.setLevel(logging.DEBUG)
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL if not verbose else logging.WARNING)
    logging.getLogger("matplotlib").setLevel(logging.WARNING)
    logging.getLogger("numba").setLevel(logging.WARNING)


def log_path_for(recording: str | Path) -> Path:
    """The log file kept beside a recording: RUN.h5 -> RUN.log."""
    return Path(recording).with_suffix(".log")


@contextlib.contextmanager
def log_file(path: Path) -> Iterator[Path]:
    """Write every log record of the run (INFO and up) to ``path`` while the block runs."""
    handler = logging.FileHandler(path, mode="w", encoding="utf-8")
    handler.setFormatter(logging.Formatter(FILE_FORMAT))
    handler.setLevel(logging.INFO)
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        yield path
    finally:
        root.removeHandler(handler)
        handler.close()
