"""Compile (or load from numba's cache) the kernels nearly every test needs, in one process.

Run by ``tests/conftest.py`` before the test workers start their tests: on a fresh checkout
each worker would otherwise compile the integrator itself at the same moment (about 45 s of
CPU each; numba's cache does not stop two processes compiling the same function at once),
and every later process loads what this one wrote.  Loading and compiling give the same
numbers (``tests/maps/test_map_command.py`` checks it in a process with a cache of its own).
"""

from __future__ import annotations

import numpy as np

from analysis.dynamics.chaos01 import zero_one_test
from analysis.model import Drive, Model, RigParameters
from analysis.simulate import SimulationSettings, simulate
from analysis.simulate.segments import integrate_segments


def main() -> None:
    """One short run of each: a forced impacting run, a shooting segment, the 0-1 test."""
    model = Model(RigParameters(), Drive(amplitude_m=0.002, frequency_hz=10.0))
    simulate(model, -0.1, 0.0, settings=SimulationSettings(duration_s=0.5, fs_hz=1000.0))
    times = np.linspace(0.0, 0.2, 21)
    integrate_segments(model.pack(), np.zeros(1), np.zeros((1, 2)), times,
                       np.array([0, times.size]))
    zero_one_test(np.sin(0.7 * np.arange(400.0)))


if __name__ == "__main__":
    main()
