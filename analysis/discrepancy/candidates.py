"""Which named causes are candidates on a record, and how a fit of each one starts.

The fitter is one general mechanism over the registry ``analysis.extensions.CAUSES``;
a cause can show in a kind of experiment when the kind provides what the cause needs
(:mod:`analysis.experiments`).  This module declares the rest: the baseline parameters
whose role a cause's parameters take over, and each parameter's finite-difference step
and start value, scaled to the record at hand.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

from analysis.experiments import experiment_kind
from analysis.extensions import CAUSES, Cause

# Baseline parameters a cause makes redundant: its own parameters play their part.
REPLACES: dict[str, tuple[str, ...]] = {
    "contact_exponent": ("K_N_per_m1.5",),
    "contact_damping_law": ("mu0_s_per_m",),
}


@dataclass(frozen=True)
class RecordScale:
    """Magnitudes of the record and its baseline fit that set steps and start values."""

    amplitude_rad: float  # largest swing
    omega_rad_s: float
    zeta: float
    duration_s: float
    dt_s: float
    inertia_kg_m2: float  # m L^2
    stiffness: float  # baseline K [N / m^1.5]
    mu0_s_per_m: float
    penetration_m: float  # typical largest penetration of the baseline's contacts (0: none)


@dataclass(frozen=True)
class ParameterPlan:
    """How one parameter is fitted: start value, finite-difference step, log scale or not."""

    start: float
    step: float
    log: bool = False


PlanMaker = Callable[[RecordScale], Mapping[str, ParameterPlan]]


def _coulomb(s: RecordScale) -> dict[str, ParameterPlan]:
    # A friction torque of 1e-4 of the largest gravity torque is already a small effect.
    torque = s.inertia_kg_m2 * s.omega_rad_s**2 * max(s.amplitude_rad, 1e-3)
    return {"Tc_N_m": ParameterPlan(0.0, 1e-4 * torque)}


def _drag(s: RecordScale) -> dict[str, ParameterPlan]:
    # c2 theta'|theta'| equals the viscous term 2 zeta omega theta' at c2 ~ 2 zeta / amplitude.
    return {"c2_per_rad": ParameterPlan(0.0, 1e-3 * max(s.zeta, 1e-3) / max(s.amplitude_rad, 1e-3))}


def _barrier(s: RecordScale) -> dict[str, ParameterPlan]:
    return {"theta_b_rad": ParameterPlan(0.0, 1e-5 * max(s.amplitude_rad, 1e-2))}


def _exponent(s: RecordScale) -> dict[str, ParameterPlan]:
    return {"n": ParameterPlan(1.5, 1e-3), "K_n": ParameterPlan(s.stiffness, 1e-3, log=True)}


def _kelvin_voigt(s: RecordScale) -> dict[str, ParameterPlan]:
    # Same dissipation per impact as the Hunt-Crossley term at half the largest penetration.
    c = s.stiffness * s.mu0_s_per_m * (0.5 * max(s.penetration_m, 1e-7)) ** 1.5
    return {"c_N_s_per_m": ParameterPlan(max(c, 1e-6), 1e-3, log=True)}


def _offset(s: RecordScale) -> dict[str, ParameterPlan]:
    return {"offset_rad": ParameterPlan(0.0, 1e-6 * max(s.amplitude_rad, 1e-2))}


def _nonlinearity(s: RecordScale) -> dict[str, ParameterPlan]:
    return {"k3": ParameterPlan(0.0, 1e-4)}


def _lag(s: RecordScale) -> dict[str, ParameterPlan]:
    # A sampled first-order lag with tau << dt is the identity to exp(-dt/tau): no gradient
    # there. Start at half a sample period, where the fit can move either way.
    return {"tau_s": ParameterPlan(0.5 * s.dt_s, 1e-2 * s.dt_s)}


def _distortion(s: RecordScale) -> dict[str, ParameterPlan]:
    return {"h2": ParameterPlan(0.02, 1e-4), "phi2_rad": ParameterPlan(0.0, 1e-3)}


def _amplitude(s: RecordScale) -> dict[str, ParameterPlan]:
    return {"eps": ParameterPlan(0.0, 1e-4)}


PLANS: dict[str, PlanMaker] = {
    "coulomb_friction": _coulomb,
    "quadratic_drag": _drag,
    "barrier_offset": _barrier,
    "contact_exponent": _exponent,
    "contact_damping_law": _kelvin_voigt,
    "sensor_offset": _offset,
    "sensor_nonlinearity": _nonlinearity,
    "sensor_lag": _lag,
    "excitation_distortion": _distortion,
    "excitation_amplitude": _amplitude,
}


def plan_for(cause: Cause, scale: RecordScale) -> dict[str, ParameterPlan]:
    """Start values and steps of a cause's parameters; a cause without a declared plan
    starts at its registry defaults with steps of 1e-6 of its parameter range."""
    maker = PLANS.get(cause.name)
    if maker is not None:
        return dict(maker(scale))
    return {
        spec.name: ParameterPlan(spec.default, 1e-6 * (spec.upper - spec.lower))
        for spec in cause.parameters
    }


def candidates_for(experiment: str) -> list[Cause]:
    """The registered causes that can show in a record of ``experiment``."""
    kind = experiment_kind(experiment)
    return [c for c in CAUSES.values() if kind.hidden_reason(c.needs) is None]


def excluded_for(experiment: str) -> dict[str, str]:
    """Causes that cannot show in a record of ``experiment``, each with the reason."""
    kind = experiment_kind(experiment)
    out = {}
    for c in CAUSES.values():
        reason = kind.hidden_reason(c.needs)
        if reason is not None:
            out[c.name] = reason
    return out
