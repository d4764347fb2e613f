"""The impact-rig command line: every declared command is listed and has its own help."""

import subprocess
import sys
from importlib.metadata import entry_points

from rig.cli import COMMAND_GROUP


def run_cli(*args):
    return subprocess.run(
        [sys.executable, "-m", "rig.cli", *args], capture_output=True, text=True, timeout=120
    )


def test_help_lists_every_declared_command():
    declared = {entry.name for entry in entry_points(group=COMMAND_GROUP)}
    assert "simulate" in declared
    result = run_cli("--help")
    assert result.returncode == 0
    for name in declared:
        assert name in result.stdout
    assert "unavailable" not in result.stdout


def test_every_command_has_help():
    for entry in entry_points(group=COMMAND_GROUP):
        result = run_cli(entry.name, "--help")
        assert result.returncode == 0, (entry.name, result.stderr)
        assert "usage: impact-rig" in result.stdout


def test_no_command_prints_help_and_fails():
    result = run_cli()
    assert result.returncode != 0
    assert "commands" in result.stdout


def test_user_errors_are_one_line_not_a_traceback(tmp_path):
    result = run_cli("identify", str(tmp_path / "missing.csv"))
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert "missing.csv" in result.stderr
