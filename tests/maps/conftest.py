"""Tiny maps for the map tests: the command's arguments and a reader of the computed arrays."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from analysis.maps import read_map
from analysis.maps.plan import IC_THETA_RAD
from rig.cli import main

# Each tiny map runs in well under a second on one core; small batches make several tasks,
# so continuation sweeps cross task boundaries.
TINY = {
    "bifurcation": [
        "bifurcation", "--f-drive-hz", "10", "--vary", "beta=0.06:0.14:6", "--ics", "2",
        "--transient-periods", "30", "--record-periods", "50", "--batch", "4",
    ],
    "regimes": [
        "regimes", "--vary", "beta=0.06:0.12:3", "--vary", "f_drive_hz=9:11:2", "--ics", "2",
        "--transient-periods", "30", "--record-periods", "50", "--batch", "5",
    ],
    "basins": [
        "basins", "--f-drive-hz", "10", "--beta", "0.08", "--vary",
        f"theta0=-{IC_THETA_RAD}:0:4", "--vary", "omega0=-4:4:3",
        "--transient-periods", "30", "--record-periods", "50", "--batch", "5",
    ],
}
COMPARED = ("trajectories", "summary", "points", "axes")


def run_map(
    *args: str, timeout: float = 120.0, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess:
    """``impact-rig map ARGS`` in a new process, as a user runs it (``env``: its whole
    environment, default this process's)."""
    return subprocess.run(
        [sys.executable, "-m", "rig.cli", "map", *args],
        capture_output=True, text=True, timeout=timeout, env=env,
    )


def map_main(capsys, *args: str) -> tuple[int, str]:
    """``impact-rig map ARGS`` through the command line's own entry, in this process (saves
    the seconds a new process spends importing); returns the exit status and stderr."""
    capsys.readouterr()
    status = main(["map", *args])
    return status, capsys.readouterr().err


def assert_same_map(first: Path, second: Path) -> None:
    """Every computed dataset of two map files equal, bit for bit (NaN where NaN)."""
    a, b = read_map(first), read_map(second)
    assert a["complete"] and b["complete"]
    assert a["settings"] == b["settings"]
    assert a["summary_info"] == b["summary_info"]
    for group in COMPARED:
        assert a[group].keys() == b[group].keys()
        for name, values in a[group].items():
            other = b[group][name]
            assert values.dtype == other.dtype, (group, name)
            same = values.tobytes() == other.tobytes()  # bit for bit, NaN payloads included
            assert same, f"{group}/{name} differs"


@pytest.fixture(scope="session")
def reference_maps(tmp_path_factory) -> dict[str, Path]:
    """Each tiny map computed in this process (--workers 1): the reference for the others."""
    folder = tmp_path_factory.mktemp("reference_maps")
    out = {}
    for kind, args in TINY.items():
        path = folder / f"{kind}.h5"
        assert main(["map", *args, "--workers", "1", "--quiet", "--out", str(path)]) == 0
        out[kind] = path
    return out


def finite_fraction(path: Path) -> float:
    """Share of trajectories that stayed in the model (guards against a map of failures)."""
    status = read_map(path)["trajectories"]["status"]
    return float(np.mean(status == 0))
