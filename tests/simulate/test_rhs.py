"""The kernel's right-hand side is analysis.model's equation, term for term."""

from __future__ import annotations

import math

import numpy as np

from analysis.model import Model, contact_force, paper_case, penetration, smooth_acceleration
from analysis.packed import P
from analysis.simulate.integrator import coefficients, region_acceleration

# a typical size of every slot of the packed vector, by name (the random draw scales it)
_TYPICAL = {
    P.OMEGA2: 200.0,
    P.TWO_ZETA_OMEGA: 0.2,
    P.INV_L: 20.0,
    P.CONTACT_GAIN: 700.0,
    P.SHAFT_L: 0.05,
    P.K: 3e5,
    P.EXPONENT: 1.5,
    P.MU0: 1.0,
    P.C_VISCOUS: 0.8,
    P.THETA_B: 0.2,
    P.SIN_THETA_B: 0.2,
    P.BARRIER: 1.0,
    P.COULOMB_ACC: 1.0,
    P.C2: 1e-2,
    P.OMEGA_DRIVE: 60.0,
    P.A1: 5e-3,
    P.A2: 1e-3,
    P.PHI2: 3.0,
    P.PHASE0: 6.0,
}


def _random_packed(rng: np.random.Generator) -> np.ndarray:
    """Every slot of the packed vector random (a new slot left out here fails the check)."""
    typical = np.array([_TYPICAL[slot] for slot in P if slot is not P.SIZE])
    p = rng.uniform(0.1, 2.0, typical.size) * typical
    p[P.EXPONENT] = rng.choice([1.5, rng.uniform(0.8, 2.5)])
    p[P.THETA_B] = rng.uniform(-0.3, 0.3)
    p[P.SIN_THETA_B] = np.sin(p[P.THETA_B])
    p[P.BARRIER] = rng.choice([0.0, 1.0])
    for slot in (P.A2, P.C2, P.C_VISCOUS, P.MU0):
        if rng.random() < 0.3:
            p[slot] = 0.0
    return p


def _rounding_scale(t: float, theta: float, theta_dot: float, p: np.ndarray) -> float:
    """Sum of the sizes of the equation's terms, each sum counted by its parts, and of the
    drive's phase error (Omega t + phase0 is rounded at its own size).

    The two forms round their terms in a different order (the kernel fuses multiply-adds),
    so they may differ by a few roundings of each part, however much the parts cancel.
    """
    phase = p[P.OMEGA_DRIVE] * t + p[P.PHASE0]
    drive = p[P.OMEGA_DRIVE] ** 2 * p[P.INV_L] * abs(math.cos(theta))
    drive *= abs(p[P.A1]) + 8.0 * abs(p[P.A2])  # bounds the drive and its phase derivative
    scale = (
        abs(p[P.TWO_ZETA_OMEGA] * theta_dot)
        + abs(p[P.C2]) * theta_dot**2
        + abs(p[P.OMEGA2] * math.sin(theta))
        + drive * (1.0 + abs(phase))
    )
    if contact_force(theta, theta_dot, p) > 0.0:
        elastic = p[P.K] * penetration(theta, p) ** p[P.EXPONENT]
        rate = abs(p[P.SHAFT_L] * math.cos(theta) * theta_dot)
        parts = elastic * (1.0 + abs(p[P.MU0]) * rate) + abs(p[P.C_VISCOUS]) * rate
        scale += abs(p[P.CONTACT_GAIN]) * parts
    return scale


def test_region_acceleration_equals_the_model_equation():
    rng = np.random.default_rng(11)
    packed = [Model().pack(), Model(*paper_case("h").dimensional()).pack()]
    packed += [_random_packed(rng) for _ in range(300)]
    for p in packed:
        free = p.copy()
        free[P.BARRIER] = 0.0
        for _ in range(20):
            t = rng.uniform(0, 100)
            theta = rng.uniform(-1.5, 1.5) if rng.random() < 0.5 else rng.uniform(-0.02, 0.3)
            theta_dot = rng.uniform(-30, 30)
            for contact, reference in ((True, p), (False, free)):
                expected = smooth_acceleration(t, theta, theta_dot, reference)
                got = region_acceleration(t, theta, theta_dot, coefficients(p, contact))
                bound = 8.0 * np.finfo(float).eps * _rounding_scale(t, theta, theta_dot, reference)
                assert abs(got - expected) <= bound, (p, theta)
