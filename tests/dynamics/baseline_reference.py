"""A baseline model's rig and drive for the scipy reference simulator (``reference``), which
shares no code with the integrator: the independent check of an orbit the project found."""

from __future__ import annotations

import numpy as np

from analysis.model import Model
from analysis.packed import P
from reference.simulator import Pendulum, TableMotion, simulate_reference


def reference_rig(model: Model) -> tuple[Pendulum, TableMotion]:
    """The reference's pendulum and table for a baseline ``model`` (no cause)."""
    rig, packed = model.rig, model.pack()
    pendulum = Pendulum(m_kg=rig.m_kg, l_m=rig.l_m, L_m=rig.L_m, zeta=rig.zeta,
                        K_n=packed[P.K], mu0_s_per_m=packed[P.MU0],
                        theta_b_rad=packed[P.THETA_B])
    table = TableMotion(amplitude_m=model.drive.amplitude_m,
                        frequency_hz=model.drive.frequency_hz)
    return pendulum, table


def reference_image(model: Model, state: np.ndarray, periods: int) -> np.ndarray:
    """(theta, theta') after ``periods`` drive periods from ``state`` at drive phase 0."""
    pendulum, table = reference_rig(model)
    end = periods / model.drive.frequency_hz
    run = simulate_reference(pendulum, table, float(state[0]), float(state[1]),
                             np.array([end]), rtol=1e-12, atol=1e-14)
    return np.array([run.theta_rad[-1], run.theta_dot_rad_s[-1]])
