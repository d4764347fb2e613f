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
) -> dict[str, float]:
    """The parameters of cause ``name`` (docs/MODEL.md keys), drawn from ``rng``."""
    viscous = 2.0 * zeta * omega_rad_s  # 1/s, the baseline's damping coefficient of theta'
    if name == "coulomb_friction":
        # dry friction dissipating 0.5-2 times the viscous damping's energy per cycle:
        # Tc <|theta'|> = r m L^2 2 zeta omega <theta'^2>; tens of uN m, a pot wiper's torque.
        # Capped at the gravity torque of a 5 % swing so that it cannot stop the swing.
        ratio = rng.uniform(0.5, 2.0)
        torque = ratio * m_kg * L_m**2 * viscous * scale.mean_square_speed / scale.mean_speed_rad_s
        cap = 0.05 * gravity_torque_N_m * math.sin(scale.amplitude_rad)
        return {"Tc_N_m": float(min(torque, cap))}
    if name == "quadratic_drag":
        # drag dissipating 0.5-2 times the viscous damping: c2 <|theta'|^3> = r 2 zeta omega
        # <theta'^2> (a bob with a vane; a bare sphere's drag is a thousand times smaller)
        ratio = rng.uniform(0.5, 2.0)
        return {"c2_per_rad": float(ratio * viscous * scale.mean_square_speed
                                    / scale.mean_cube_speed)}
    if name == "barrier_offset":
        # a gap or preload of 0.4-1.5 mm at the contact point
        return {"theta_b_rad": float(rng.uniform(0.008, 0.03) * rng.choice([-1.0, 1.0]))}
    if name == "contact_exponent":
        # a law that gives Hertz's force at the typical penetration but bends away from it;
        # at one impact speed it trades off against K, so only a clear bend shows at all
        low, high = rng.uniform(1.0, 1.25), rng.uniform(1.8, 2.2)
        n = float(low if rng.random() < 0.5 else high)
        delta = typical_penetration_m(scale.impact_speed_m_s, m_kg=m_kg, l_m=l_m, L_m=L_m,
                                      K_N_per_m1_5=K_N_per_m1_5)
        return {"n": n, "K_n": float(K_N_per_m1_5 * delta ** (1.5 - n))}
    if name == "contact_damping_law":
        # Kelvin-Voigt damping with Hunt-Crossley's damping force at the typical penetration
        delta = typical_penetration_m(scale.impact_speed_m_s, m_kg=m_kg, l_m=l_m, L_m=L_m,
                                      K_N_per_m1_5=K_N_per_m1_5)
        factor = rng.uniform(0.5, 1.5)
        return {"c_N_s_per_m": float(factor * K_N_per_m1_5 * mu0_s_per_m * delta**1.5)}
    if name == "sensor_offset":
        return {"offset_rad": float(rng.uniform(0.005, 0.03) * rng.choice([-1.0, 1.0]))}
    if name == "sensor_nonlinearity":
        # a cubic linearity error of 5-15 noise sigmas at the swing's largest angle:
        # 1.5-30 mrad, at most half a percent of a potentiometer's 6 rad track
        error = rng.uniform(5.0, 15.0) * noise_rad
        k3 = min(error / scale.amplitude_rad**3, 2.0)
        return {"k3": float(k3 * rng.choice([-1.0, 1.0]))}
    if name == "sensor_lag":
        # an analog anti-alias filter of 2-8 ms: tau <|theta'|> is several noise sigmas
        return {"tau_s": float(rng.uniform(2e-3, 8e-3))}
    if name == "excitation_distortion":
        return {"h2": float(rng.uniform(0.05, 0.2)), "phi2_rad": float(rng.uniform(-math.pi,
                                                                                  math.pi))}
    if name == "excitation_amplitude":
        return {"eps": float(rng.uniform(0.05, 0.2) * rng.choice([-1.0, 1.0]))}
    raise ValueError(f"unknown cause {name!r}; expected one of {', '.join(CHOICES)}")


def typical_penetration_m(
    speed_m_s: float, *, m_kg: float, l_m: float, L_m: float, K_N_per_m1_5: float
) -> float:
    """Deepest penetration of a Hertz impact at ``speed_m_s`` (docs/MODEL.md section 4)."""
    m_eff = m_kg * L_m**2 / l_m**2
    return (5.0 * m_eff * speed_m_s**2 / (4.0 * K_N_per_m1_5)) ** 0.4
