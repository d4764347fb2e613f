"""Where a file came from: software and dependency versions, git commit, command line, host,
start time and operator, recorded in every recording, sidecar and report.

The command line and the operator are set once per process by the command dispatcher
(:func:`set_invocation`); a library call records what it was called from instead.
"""

from __future__ import annotations

import functools
import platform
import socket
import subprocess
import sys
from datetime import UTC, datetime
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from analysis.json_output import to_json_text

PACKAGE = "impact-rig"
DEPENDENCIES = ("numpy", "scipy", "h5py", "numba", "pymodbus")
GIT_TIMEOUT_S = 5.0

_invocation: dict[str, Any] = {"command_line": None, "operator": ""}


def package_version(name: str = PACKAGE) -> str:
    """The installed version of ``name`` ('not installed' when it is not)."""
    try:
        return version(name)
    except PackageNotFoundError:
        return "not installed"


@functools.cache
def git_commit() -> dict[str, Any] | None:
    """The commit of the source tree this code runs from, and whether it had local changes;
    None when it does not run from a git checkout (an installed wheel)."""
    root = Path(__file__).resolve().parents[1]
    if not (root / ".git").exists():
        return None
    try:
        head = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True, text=True, timeout=GIT_TIMEOUT_S, check=True,
        ).stdout.strip()
        changes = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=GIT_TIMEOUT_S, check=True,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return {"commit": head, "local_changes": bool(changes)}


def set_invocation(command_line: list[str], operator: str = "") -> None:
    """Remember how this process was started (the dispatcher calls this once)."""
    _invocation["command_line"] = list(command_line)
    _invocation["operator"] = operator


def invocation_operator() -> str:
    """The operator given on the command line ('' when none was)."""
    return str(_invocation["operator"])


def provenance(*, operator: str | None = None, start_time_utc: str | None = None) -> dict[str, Any]:
    """The provenance block: what made a file, where, when, by whom and how it was asked for."""
    command_line = _invocation["command_line"]
    return {
        "software": {"impact-rig": package_version()},
        "python": platform.python_version(),
        "dependencies": {name: package_version(name) for name in DEPENDENCIES},
        "git": git_commit(),
        "command_line": command_line if command_line is not None else list(sys.argv),
        "host": socket.gethostname(),
        "start_time_utc": start_time_utc or datetime.now(UTC).isoformat(),
        "operator": operator if operator is not None else invocation_operator(),
    }


def png_metadata() -> dict[str, str]:
    """A figure's provenance as PNG text chunks (``savefig(path, metadata=png_metadata())``):
    'Software' the version, 'Source' the command line, 'Provenance' the whole block as JSON."""
    block = provenance()
    return {
        "Software": f"{PACKAGE} {block['software'][PACKAGE]}",
        "Source": " ".join(block["command_line"]),
        "Provenance": to_json_text(block, one_line=True),
    }


def markdown_provenance() -> list[str]:
    """The closing lines of a Markdown report: the provenance block in one sentence."""
    block = provenance()
    git = block["git"]
    commit = ""
    if git:
        changes = " with local changes" if git["local_changes"] else ""
        commit = f", git {git['commit'][:12]}{changes}"
    dependencies = ", ".join(f"{name} {v}" for name, v in block["dependencies"].items())
    operator = f" by {block['operator']}" if block["operator"] else ""
    return [
        "",
        "---",
        "",
        f"Made by {PACKAGE} {block['software'][PACKAGE]}{commit} (Python {block['python']}, "
        f"{dependencies}) on {block['host']} at {block['start_time_utc']}{operator}: "
        f"`{' '.join(block['command_line'])}`",
    ]
