"""The registry of named quantities: every model parameter the code, the reports and the
config know, by its JSON key (docs/MODEL.md section 7, SI unit in the name).

Each quantity is defined once here, with its unit, symbol, one-line meaning and, where
they are physical, its bounds; the code spells a key only through this module's
constants (``from analysis import quantities as q``, then ``values[q.theta_b_rad]``), so
a key is written once and a misspelt one fails at import.  A constant is the key itself,
a plain ``str``: the JSON and CSV files read and write exactly the keys they always did.
The named causes (:mod:`analysis.extensions`) take their parameters' names, units and
meanings from these entries.  ``tests/model/test_quantities.py`` fails where a runtime
module spells a registered key as a string literal outside this module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Quantity:
    """One named quantity: its JSON key, SI unit (``""``: dimensionless), symbol in
    docs/MODEL.md, one-line meaning, and the interval a real rig's value lies in (None
    where nothing physical bounds it)."""

    key: str
    unit: str
    symbol: str
    meaning: str
    bounds: tuple[float, float] | None = None

    @property
    def doc(self) -> str:
        """The meaning with its unit, for messages: ``"barrier surface angle, rad"``."""
        return f"{self.meaning}, {self.unit}" if self.unit else self.meaning


QUANTITIES: dict[str, Quantity] = {}


def _define(key: str, unit: str, symbol: str, meaning: str,
            bounds: tuple[float, float] | None = None) -> str:
    if key in QUANTITIES:
        raise ValueError(f"quantity {key!r} is defined twice")
    QUANTITIES[key] = Quantity(key, unit, symbol, meaning, bounds)
    return key


def quantity(key: str) -> Quantity:
    """The registered quantity under JSON key ``key``, with a clear error otherwise."""
    try:
        return QUANTITIES[key]
    except KeyError:
        raise KeyError(f"unknown quantity {key!r}; known: {', '.join(QUANTITIES)}") from None


_POSITIVE = (0.0, math.inf)

# ---------------------------------------------------------------- the rig (section 3)
m_kg = _define("m_kg", "kg", "m", "pendulum mass", _POSITIVE)
l_m = _define("l_m", "m", "l", "pivot to contact point (shaft length)", _POSITIVE)
L_m = _define("L_m", "m", "L", "effective length", _POSITIVE)
R_m = _define("R_m", "m", "R", "sphere radius", _POSITIVE)
g_m_s2 = _define("g_m_s2", "m/s^2", "g", "gravitational acceleration", _POSITIVE)

# ---------------------------------------------------------------- the baseline (section 7)
omega_rad_s = _define("omega_rad_s", "rad/s", "omega", "small-angle natural frequency sqrt(g/L)",
                      _POSITIVE)
zeta = _define("zeta", "", "zeta", "viscous damping ratio", (0.0, math.inf))
K_N_per_m1_5 = _define("K_N_per_m1.5", "N/m^1.5", "K", "Hertz stiffness K = (4/3) E sqrt(R)",
                       _POSITIVE)
E_Pa = _define("E_Pa", "Pa", "E", "effective barrier modulus", _POSITIVE)
mu0_s_per_m = _define("mu0_s_per_m", "s/m", "mu0", "Hunt-Crossley constant", (0.0, math.inf))
theta_b_rad = _define("theta_b_rad", "rad", "theta_b", "barrier surface angle",
                      (-math.pi / 2, math.pi / 2))
theta0_rad = _define("theta0_rad", "rad", "theta_0", "initial angle of a decay record",
                     (-math.pi, math.pi))

# ---------------------------------------------------------------- the causes (section 6)
Tc_N_m = _define("Tc_N_m", "N m", "Tc", "pivot dry-friction torque", (0.0, math.inf))
c2_per_rad = _define("c2_per_rad", "1/rad", "c2", "aerodynamic drag coefficient", (0.0, math.inf))
n = _define("n", "", "n", "force-penetration exponent", _POSITIVE)
K_n = _define("K_n", "N/m^n", "K_n", "contact stiffness", _POSITIVE)
c_N_s_per_m = _define("c_N_s_per_m", "N s/m", "c", "Kelvin-Voigt contact damping",
                      (0.0, math.inf))
h2 = _define("h2", "", "h2", "second-harmonic amplitude ratio", (0.0, math.inf))
phi2_rad = _define("phi2_rad", "rad", "phi2", "second-harmonic phase")
eps = _define("eps", "", "eps", "relative error of the stated amplitude", (-1.0, math.inf))
offset_rad = _define("offset_rad", "rad", "offset", "sensor zero offset")
k3 = _define("k3", "1/rad^2", "k3", "cubic linearity error")
tau_s = _define("tau_s", "s", "tau", "first-order low-pass time constant", (0.0, math.inf))
