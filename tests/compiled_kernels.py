"""Compile (or load from numba's cache) the kernels nearly every test needs, in two processes.

Run by ``tests/conftest.py`` before the test workers start their tests: on a fresh checkout
each worker would otherwise compile the integrator itself at the same moment (about 45 s of
CPU each; numba's cache does not stop two processes compiling the same function at once),
and every later process loads what this one wrote.  The sensitivities' kernel (the fits'
Jacobians) and the 0-1 test's compile in a second process (``--beside``) while this one
compiles the integrator and the shooting segments that call it, on the other core, so the
workers wait only as long as the integrator takes, and none compiles the sensitivities
for itself.

Given a folder, it also draws the tiny bifurcation map of ``tests/maps`` there
(``compiled.h5``) and says in ``compiled.json`` whether this process compiled the integrator
or loaded it: a map from a process that compiled it is what
``tests/maps/test_map_command.py`` compares with one from a process that loads the cache,
so on a fresh checkout that test need not compile the integrator a second time.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from analysis.dynamics.chaos01 import zero_one_test
from analysis.model import Drive, Model, RigParameters
from analysis.packed import P
from analysis.simulate import SimulationSettings, integrator, simulate
from analysis.simulate.segments import integrate_segments
from analysis.simulate.sensitivity import DEFAULT_SENSITIVITY_SETTINGS
from analysis.simulate.variational import REC_SIZE, propagate

MAP_NAME = "compiled.h5"
VERDICT_NAME = "compiled.json"
BESIDE = "--beside"


def beside() -> None:
    """The sensitivities' kernel and the 0-1 test's: what :func:`main` leaves to a second
    process.  Neither calls the integrator's kernel (the sensitivities replay a run's record
    of segments), so this process compiles nothing :func:`main` compiles but the model's
    small helpers."""
    p = Model(RigParameters(), Drive(amplitude_m=0.002, frequency_hz=10.0)).pack()
    columns = np.array([int(P[name]) for name in DEFAULT_SENSITIVITY_SETTINGS.parameters],
                       dtype=np.int64)
    # typed as simulate_sensitivities passes them, for a run that recorded no segment
    propagate(p, columns, 0.0, -0.1, 0.0, False, 0.0, np.empty((1024, REC_SIZE)), 0,
              np.array([0.1]), 0, np.full((1, 2, 2 + columns.size), np.nan))
    zero_one_test(np.sin(0.7 * np.arange(400.0)))


def main(folder: Path | None = None) -> None:
    """One short forced impacting run and a shooting segment here while a second process
    runs :func:`beside`; and with ``folder``, the tiny bifurcation map and whether the
    integrator was compiled here."""
    other = subprocess.Popen([sys.executable, "-m", "tests.compiled_kernels", BESIDE])
    model = Model(RigParameters(), Drive(amplitude_m=0.002, frequency_hz=10.0))
    simulate(model, -0.1, 0.0, settings=SimulationSettings(duration_s=0.5, fs_hz=1000.0))
    compiled = bool(integrator.integrate.stats.cache_misses)
    times = np.linspace(0.0, 0.2, 21)  # calls the kernel just compiled or loaded
    integrate_segments(model.pack(), np.zeros(1), np.zeros((1, 2)), times,
                       np.array([0, times.size]))
    other.wait()
    if folder is None:
        return
    from rig.cli import main as cli
    from tests.maps.conftest import TINY

    status = cli(["map", *TINY["bifurcation"], "--workers", "1", "--quiet",
                  "--out", str(folder / MAP_NAME)])
    (folder / VERDICT_NAME).write_text(json.dumps({"compiled": compiled, "status": status}))


if __name__ == "__main__":
    if sys.argv[1:] == [BESIDE]:
        beside()
    else:
        main(Path(sys.argv[1]) if len(sys.argv) > 1 else None)
