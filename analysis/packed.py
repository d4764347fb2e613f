"""The packed parameter vector the compiled equations read, and the error of a bad parameter.

A leaf of :mod:`analysis`: the model packs the vector, the named causes of
:mod:`analysis.extensions` write their terms into it, and the integrators read it,
so its layout lives here, below all of them.
"""

from __future__ import annotations

from enum import IntEnum


class ParameterError(ValueError):
    """A model parameter is missing, unknown or outside its physical range."""


class P(IntEnum):
    """Indices of the packed parameter vector the compiled equations read.

    The vector is the superset model: baseline terms plus every extension slot,
    each extension slot neutral (zero, or n = 1.5) unless a cause sets it.
    """

    OMEGA2 = 0  # g / L                        [1/s^2]
    TWO_ZETA_OMEGA = 1  # 2 zeta omega          [1/s]
    INV_L = 2  # 1 / L, scales table acceleration [1/m]
    CONTACT_GAIN = 3  # l / (m L^2)             [1/(kg m)]
    SHAFT_L = 4  # l, pivot to contact point     [m]
    K = 5  # contact stiffness K_n               [N / m^n]
    EXPONENT = 6  # force-penetration exponent n (1.5 = Hertz)
    MU0 = 7  # Hunt-Crossley constant            [s/m]
    C_VISCOUS = 8  # Kelvin-Voigt contact damping [N s/m]
    THETA_B = 9  # barrier angle                 [rad]
    SIN_THETA_B = 10  # sin(theta_b)
    BARRIER = 11  # 1.0 barrier present, 0.0 removed
    COULOMB_ACC = 12  # Tc / (m L^2)             [1/s^2]
    C2 = 13  # quadratic drag coefficient        [1/rad]
    OMEGA_DRIVE = 14  # Omega                    [rad/s]
    A1 = 15  # table amplitude, fundamental      [m]
    A2 = 16  # table amplitude, 2nd harmonic     [m]
    PHI2 = 17  # phase of the 2nd harmonic       [rad]
    PHASE0 = 18  # drive phase at t = 0, keeps it continuous when Omega changes [rad]
    SIZE = 19
