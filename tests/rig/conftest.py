"""Fixtures for the rig tests: small or read-only filesystems mounted for one test."""

from __future__ import annotations

import contextlib
import subprocess
from pathlib import Path

import pytest


@contextlib.contextmanager
def mounted_tmpfs(where: Path, options: str):
    """Mount a tmpfs at ``where`` with ``options`` (skip the test when mounting is not allowed)."""
    where.mkdir(parents=True, exist_ok=True)
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        pytest.skip(
            f"cannot mount a tmpfs here (needs root in a sandbox that allows mounts): "
            f"{done.stderr.strip() or done.returncode}"
        )
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False, capture_output=True)


@pytest.fixture
def tiny_filesystem(tmp_path):
    """A 6 MiB filesystem: a fast recording there runs out of space within seconds."""
    with mounted_tmpfs(tmp_path / "tiny", "size=6m") as where:
        yield where


@pytest.fixture
def read_only_folder(tmp_path):
    """A folder nobody can write to, not even root (a read-only mount)."""
    with mounted_tmpfs(tmp_path / "ro", "ro,size=1m") as where:
        yield where


@pytest.fixture
def two_megabyte_filesystem(tmp_path):
    """Room for a few seconds of a 20 kHz recording."""
    with mounted_tmpfs(tmp_path / "small", "size=2m") as where:
        yield where
