"""A model from named parameter values (docs/MODEL.md section 7 keys) and the causes switched on.

Fits work on a flat dict of values: the baseline's ``omega_rad_s``, ``zeta``,
``K_N_per_m1.5`` and ``mu0_s_per_m`` and each active cause's own parameters.  This module
turns such a dict into the model (for the integrator) and into the angle the sensor
reports, so identification and discrepancy analysis build their models the same way.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from analysis import quantities as q
from analysis.extensions import NONE, cause, measurement_chain
from analysis.model import Drive, Model, RigParameters
from analysis.packed import P


def model_from_values(
    rig: RigParameters, drive: Drive, barrier: bool, values: Mapping[str, float],
    causes: Sequence[str] = (),
) -> Model:
    """The model with L from omega (L = g / omega^2), zeta, K and mu0 from ``values`` (the
    rig's own where absent) and every cause of ``causes`` switched on with its values."""
    updates = {q.L_m: rig.g_m_s2 / values[q.omega_rad_s] ** 2, q.zeta: values[q.zeta]}
    if q.mu0_s_per_m in values:
        updates[q.mu0_s_per_m] = values[q.mu0_s_per_m]
    fitted = rig.with_values(**updates)
    if q.K_N_per_m1_5 in values:
        fitted = fitted.with_stiffness(values[q.K_N_per_m1_5])
    model = Model(rig=fitted, drive=drive, barrier=barrier)
    for name in causes:
        if name == NONE:
            continue
        c = cause(name)
        model = model.with_extension(
            name, **{s.name: values[s.name] for s in c.parameters if s.name in values}
        )
    return model


def packed_from_values(
    rig: RigParameters, drive: Drive, barrier: bool, values: Mapping[str, float],
    causes: Sequence[str] = (), phase0_rad: float = 0.0,
) -> np.ndarray:
    """The packed vector of :func:`model_from_values`, with the drive phase at t = 0."""
    p = model_from_values(rig, drive, barrier, values, causes).pack()
    p[P.PHASE0] = phase0_rad
    return p


def measured_angle(
    causes: Sequence[str], values: Mapping[str, float], t: np.ndarray, theta: np.ndarray,
    theta_dot0: float | None = None,
) -> np.ndarray:
    """The angle the sensor reports for the true angle ``theta`` at uniform times ``t``:
    every measurement cause of ``causes``, along the sensor chain (``Cause.measurement_stage``:
    filter, linearity, zero) whatever their order in ``causes`` (``theta_dot0``, the rate at
    the first sample, settles a filter's memory there)."""
    out = np.asarray(theta, dtype=float)
    for c in measurement_chain(causes):
        own = {s.name: values[s.name] for s in c.parameters if s.name in values}
        out = c.measurement(np.asarray(t, dtype=float), out, c.values(own), theta_dot0)
    return out


def measurement_has_memory(causes: Sequence[str]) -> bool:
    """True when the sensor of ``causes`` reads a sample through earlier ones (a filter)."""
    return any(name != NONE and cause(name).measurement_memory for name in causes)


def has_measurement(causes: Sequence[str]) -> bool:
    """True when some cause of ``causes`` acts on the measured angle."""
    return any(name != NONE and cause(name).measurement is not None for name in causes)
