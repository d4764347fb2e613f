"""The integrator's compiled right-hand side is analysis.model's equation in every region.

The integrator inlines the model's equations into its own kernels (compiled there, with
their flags, and cached per file); here states drawn into each region of the motion
are evaluated both ways, for the baseline and for every cause that changes the dynamics.
The integrator's side is what a run uses: the region ``new_state`` puts the state in
(contact or free flight, sliding direction or stuck) and the kernel ``rhs`` there.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.extensions import CAUSES
from analysis.model import (
    Drive,
    Model,
    RigParameters,
    acceleration,
    coefficients,
    contact_force,
    paper_case,
    penetration,
    smooth_acceleration,
)
from analysis.packed import P
from analysis.simulate import integrator as ig

DYNAMICS_CAUSES = sorted(name for name, c in CAUSES.items() if c.acts_on == "dynamics")

# Where a state can be: the barrier's regions, and with friction the two at theta' = 0.
GEOMETRIC_REGIONS = {
    "flight",  # theta < theta_b
    "contact_loading",  # in contact, theta' > 0
    "contact_unloading",  # in contact, theta' < 0, the force still pushing
    "contact_clamped",  # in contact, separating so fast that the force would pull: 0
    "beyond_horizontal",  # sin(theta) > sin(theta_b) but cos(theta) < 0: no barrier there
    "barrier_removed",  # theta > theta_b with the barrier taken out
}
REST_REGIONS = {"at_rest_stuck", "at_rest_released"}  # theta' = 0 with Coulomb friction

# Both sides round each term a few times; the drive's phase Omega t + phase0 is rounded at
# its own size.  With no fast-math flags on either side they agree to the last bit under
# this numba and LLVM; the bound does not rely on that.
ROUNDINGS = 8.0 * np.finfo(float).eps


def _random_rig(rng: np.random.Generator) -> RigParameters:
    base = RigParameters()
    scale = lambda: rng.uniform(0.5, 2.0)  # noqa: E731
    return RigParameters(
        m_kg=base.m_kg * scale(),
        l_m=base.l_m * scale(),
        L_m=base.L_m * scale(),
        R_m=base.R_m * scale(),
        g_m_s2=base.g_m_s2 * rng.uniform(0.9, 1.1),
        zeta=base.zeta * scale(),
        E_Pa=base.E_Pa * scale(),
        mu0_s_per_m=rng.uniform(0.2, 2.0),
        theta_b_rad=rng.uniform(-0.2, 0.2),
    )


def _cause_values(rng: np.random.Generator, name: str, rig: RigParameters) -> dict[str, float]:
    """Values of cause ``name`` inside what a real rig can have, the stiffness of a general
    power law near Hertz's at a millimetre's penetration."""
    values = {}
    for spec in CAUSES[name].parameters:
        low, high = spec.plausible or (spec.lower, spec.upper)
        values[spec.name] = rng.uniform(low, high)
    if name == "contact_exponent":
        values["K_n"] = rig.K_N_per_m1_5 * 1e-3 ** (1.5 - values["n"]) * 10 ** rng.uniform(-1, 1)
    if name == "coulomb_friction":  # from a trace to a torque that holds most swings
        values["Tc_N_m"] = 10 ** rng.uniform(-6, math.log10(values["Tc_N_m"] + 1e-6))
    return values


def _random_model(rng: np.random.Generator, cause: str | None) -> Model:
    rig = _random_rig(rng)
    drive = Drive()
    forced = rng.random() < 0.7 or cause in ("excitation_distortion", "excitation_amplitude")
    if forced:
        drive = Drive(amplitude_m=10 ** rng.uniform(-4, -2), frequency_hz=rng.uniform(1, 20))
    model = Model(rig, drive, barrier=rng.random() < 0.85)
    if cause is not None:
        model = model.with_extension(cause, **_cause_values(rng, cause, rig))
    return model


def _draw_state(rng: np.random.Generator, p: np.ndarray, target: str) -> tuple[float, float]:
    """(theta, theta') aimed at region ``target`` (where it lands is classified afterwards)."""
    theta_b = p[P.THETA_B]
    depth = 10 ** rng.uniform(-5, -1)  # below or beyond the barrier surface [rad]
    speed = 10 ** rng.uniform(-2, 2.5)  # [rad/s]
    if target == "flight":
        return theta_b - rng.uniform(1e-6, 1.2), rng.choice([-1.0, 1.0]) * speed
    if target == "contact_loading":
        return theta_b + depth, speed
    if target in ("contact_unloading", "contact_clamped", "barrier_removed"):
        return theta_b + depth, -speed
    if target == "beyond_horizontal":
        return rng.uniform(math.pi / 2 + 1e-3, math.pi - abs(theta_b) - 1e-3), -speed
    # at rest: near the barrier or the hanging position, where friction can hold
    return rng.choice([theta_b + depth, rng.uniform(-0.05, 0.05)]), 0.0


def _region(t: float, theta: float, theta_dot: float, p: np.ndarray) -> str:
    """The region the model puts a state in."""
    if theta_dot == 0.0 and p[P.COULOMB_ACC] > 0.0:
        held = abs(smooth_acceleration(t, theta, 0.0, p)) <= p[P.COULOMB_ACC]
        return "at_rest_stuck" if held else "at_rest_released"
    if math.sin(theta) <= p[P.SIN_THETA_B]:
        return "flight"
    if p[P.BARRIER] == 0.0:
        return "barrier_removed"
    if math.cos(theta) <= 0.0:
        return "beyond_horizontal"
    if contact_force(theta, theta_dot, p) == 0.0:
        return "contact_clamped"
    return "contact_loading" if theta_dot > 0.0 else "contact_unloading"


def _rounding_scale(t: float, theta: float, theta_dot: float, p: np.ndarray) -> float:
    """Sum of the sizes of the equation's terms, each counted by its parts (however much
    they cancel), the drive's by its phase too."""
    phase = p[P.OMEGA_DRIVE] * t + p[P.PHASE0]
    drive = p[P.OMEGA_DRIVE] ** 2 * p[P.INV_L] * abs(math.cos(theta))
    drive *= abs(p[P.A1]) + 8.0 * abs(p[P.A2])  # bounds the drive and its phase derivative
    scale = (
        abs(p[P.TWO_ZETA_OMEGA] * theta_dot)
        + p[P.C2] * theta_dot**2
        + abs(p[P.OMEGA2] * math.sin(theta))
        + drive * (1.0 + abs(phase))
        + p[P.COULOMB_ACC]
    )
    delta = penetration(theta, p)
    if p[P.BARRIER] != 0.0 and math.cos(theta) > 0.0 and delta > 0.0:
        rate = abs(p[P.SHAFT_L] * math.cos(theta) * theta_dot)
        elastic = p[P.K] * delta ** p[P.EXPONENT]
        scale += p[P.CONTACT_GAIN] * (elastic * (1.0 + p[P.MU0] * rate) + p[P.C_VISCOUS] * rate)
    return scale


def _model_side(t: float, theta: float, theta_dot: float, p: np.ndarray, region: str) -> float:
    """theta'' by the model: sliding against friction, or from rest once released."""
    if region == "at_rest_released":
        smooth = smooth_acceleration(t, theta, 0.0, p)
        return smooth - math.copysign(p[P.COULOMB_ACC], smooth)
    return acceleration(t, theta, theta_dot, p)


def _integrator_side(t: float, theta: float, theta_dot: float, p: np.ndarray) -> float | None:
    """theta'' the integrator integrates from this state (None: held stuck)."""
    state = ig.new_state(t, theta, theta_dot, p)
    in_contact = state[ig.S_CONTACT] != 0.0
    expected_contact = (
        p[P.BARRIER] != 0.0 and math.cos(theta) > 0.0 and penetration(theta, p) > 0.0
    )
    assert in_contact == expected_contact, (theta, theta_dot, p)
    slide = state[ig.S_SLIDE]
    if slide == 0.0:
        return None
    return ig.rhs(t, theta, theta_dot, coefficients(p, in_contact), slide, p[P.COULOMB_ACC])


def _models(cause: str | None, rng: np.random.Generator) -> list[Model]:
    models = [_random_model(rng, cause) for _ in range(60)]
    if cause is None:
        models += [Model(), Model(*paper_case("h").dimensional())]
    else:  # the cause is switched on: it changes the packed vector
        for model in models:
            plain = Model(model.rig, model.drive, model.barrier)
            assert not np.array_equal(model.pack(), plain.pack()), cause
    return models


@pytest.mark.parametrize("cause", [None, *DYNAMICS_CAUSES])
def test_integrator_rhs_is_the_model_equation_in_every_region(cause):
    rng = np.random.default_rng(17 + (DYNAMICS_CAUSES.index(cause) if cause else -1))
    targets = sorted(GEOMETRIC_REGIONS | (REST_REGIONS if cause == "coulomb_friction" else set()))
    hits = dict.fromkeys(targets, 0)
    for model in _models(cause, rng):
        p = model.pack()
        for target in targets:
            for _ in range(6):
                t = rng.uniform(0.0, 100.0)
                theta, theta_dot = _draw_state(rng, p, target)
                region = _region(t, theta, theta_dot, p)
                hits[region] += 1
                got = _integrator_side(t, theta, theta_dot, p)
                if region == "at_rest_stuck":
                    assert got is None, (theta, p)
                    continue
                expected = _model_side(t, theta, theta_dot, p, region)
                bound = ROUNDINGS * _rounding_scale(t, theta, theta_dot, p)
                # a stale numba cache of the integrator (after the equations in
                # analysis/model.py changed) fails here: delete analysis/simulate/__pycache__
                assert got is not None and abs(got - expected) <= bound, (
                    region, theta, theta_dot, got, expected, p)
    assert all(count >= 20 for count in hits.values()), hits
