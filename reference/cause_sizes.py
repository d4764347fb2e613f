"""How large each named cause of docs/MODEL.md section 6 is drawn in a forced record: a size a
real rig can have, scaled to the response it acts on so that it shows above the noise.

Parameter names and units are those of docs/MODEL.md sections 6 and 7.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CAUSES = (
    "coulomb_friction",
    "quadratic_drag",
    "barrier_offset",
    "contact_exponent",
    "contact_damping_law",
    "sensor_offset",
    "sensor_nonlinearity",
    "sensor_lag",
    "excitation_distortion",
    "excitation_amplitude",
)
CHOICES = ("none", *CAUSES)


@dataclass(frozen=True)
class ResponseScale:
    """What a pilot run of the baseline shows about the response a cause will act on."""

    amplitude_rad: float  # largest |theta|
    mean_speed_rad_s: float  # <|theta'|>
    mean_square_speed: float  # <theta'^2>, (rad/s)^2
    mean_cube_speed: float  # <|theta'|^3>, (rad/s)^3
    impact_speed_m_s: float  # median contact entry speed l cos(theta) theta'


def draw_cause_values(
    rng: np.random.Generator,
    name: str,
    scale: ResponseScale,
    *,
    m_kg: float,
    l_m: float,
    L_m: float,
    zeta: float,
    omega_rad_s: float,
    K_N_per_m1_5: float,
    mu0_s_per_m: float,
    noise_rad: float,
    gravity_torque_N_m: float,
    at_least: float = 0.0,
) -> dict[str, float]:
    """The parameters of cause ``name`` (docs/MODEL.md keys), drawn from ``rng``.

    ``at_least`` in [0, 1) is the quantile of the size's plausible range the draw starts
    from: 0 draws over the whole range, 0.5 from its larger half (a redraw of a cause the
    record did not show).
    """
    if not 0.0 <= at_least < 1.0:
        raise ValueError(f"at_least = {at_least!r}: expected a quantile in [0, 1)")

    def size(low: float, high: float) -> float:
        return float(rng.uniform(low + at_least * (high - low), high))

    viscous = 2.0 * zeta * omega_rad_s  # 1/s, the baseline's damping coefficient of theta'
    if name == "coulomb_friction":
        # dry friction dissipating 0.5-8 times the viscous damping's energy per cycle:
        # Tc <|theta'|> = r m L^2 2 zeta omega <theta'^2>; tens to hundreds of uN m, what a
        # conductive-plastic potentiometer's wiper takes (0.1-1 mN m).  Below about 4 times
        # the viscous damping a 10 Hz record's refit of zeta absorbs it.  Capped at the
        # gravity torque of a 10 % swing so that it cannot stop the swing.
        ratio = size(0.5, 8.0)
        torque = ratio * m_kg * L_m**2 * viscous * scale.mean_square_speed / scale.mean_speed_rad_s
        cap = 0.1 * gravity_torque_N_m * math.sin(scale.amplitude_rad)
        return {"Tc_N_m": float(min(torque, cap))}
    if name == "quadratic_drag":
        # drag dissipating 0.5-2 times the viscous damping: c2 <|theta'|^3> = r 2 zeta omega
        # <theta'^2> (a bob with a vane; a bare sphere's drag is a thousand times smaller)
        ratio = size(0.5, 2.0)
        return {"c2_per_rad": float(ratio * viscous * scale.mean_square_speed
                                    / scale.mean_cube_speed)}
    if name == "barrier_offset":
        # a gap or preload of 0.4-1.5 mm at the contact point
        return {"theta_b_rad": size(0.008, 0.03) * float(rng.choice([-1.0, 1.0]))}
    if name == "contact_exponent":
        # a law that gives Hertz's force at the typical penetration but bends away from it;
        # at one impact speed it trades off against K, so only a clear bend shows at all
        low = rng.uniform(1.0, 1.25 - 0.25 * at_least)  # larger: further from 1.5
        high = size(1.8, 2.2)
        n = float(low if rng.random() < 0.5 else high)
        delta = typical_penetration_m(scale.impact_speed_m_s, m_kg=m_kg, l_m=l_m, L_m=L_m,
                                      K_N_per_m1_5=K_N_per_m1_5)
        return {"n": n, "K_n": float(K_N_per_m1_5 * delta ** (1.5 - n))}
    if name == "contact_damping_law":
        # Kelvin-Voigt damping with Hunt-Crossley's damping force at the typical penetration
        delta = typical_penetration_m(scale.impact_speed_m_s, m_kg=m_kg, l_m=l_m, L_m=L_m,
                                      K_N_per_m1_5=K_N_per_m1_5)
        factor = size(0.5, 1.5)
        return {"c_N_s_per_m": float(factor * K_N_per_m1_5 * mu0_s_per_m * delta**1.5)}
    if name == "sensor_offset":
        return {"offset_rad": size(0.005, 0.03) * float(rng.choice([-1.0, 1.0]))}
    if name == "sensor_nonlinearity":
        # a cubic linearity error of 5-15 noise sigmas at the swing's largest angle:
        # 1.5-30 mrad, at most half a percent of a potentiometer's 6 rad track
        error = size(5.0, 15.0) * noise_rad
        k3 = min(error / scale.amplitude_rad**3, 2.0)
        return {"k3": float(k3 * rng.choice([-1.0, 1.0]))}
    if name == "sensor_lag":
        # an analog anti-alias filter of 2-8 ms: tau <|theta'|> is several noise sigmas
        return {"tau_s": size(2e-3, 8e-3)}
    if name == "excitation_distortion":
        return {"h2": size(0.05, 0.2), "phi2_rad": float(rng.uniform(-math.pi, math.pi))}
    if name == "excitation_amplitude":
        return {"eps": size(0.05, 0.2) * float(rng.choice([-1.0, 1.0]))}
    raise ValueError(f"unknown cause {name!r}; expected one of {', '.join(CHOICES)}")


def typical_penetration_m(
    speed_m_s: float, *, m_kg: float, l_m: float, L_m: float, K_N_per_m1_5: float
) -> float:
    """Deepest penetration of a Hertz impact at ``speed_m_s`` (docs/MODEL.md section 4)."""
    m_eff = m_kg * L_m**2 / l_m**2
    return (5.0 * m_eff * speed_m_s**2 / (4.0 * K_N_per_m1_5)) ** 0.4
