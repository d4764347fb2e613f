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
import numbers
from dataclasses import dataclass

from analysis.packed import ParameterError


@dataclass(frozen=True)
class Bounds:
    """The interval a real value of a quantity lies in: ``low`` and ``high`` (infinite
    where nothing bounds it), each open (the value never equals it) or closed."""

    low: float = -math.inf
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False

    def __contains__(self, value: float) -> bool:
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def words(self) -> str:
        """The interval in words for messages: ``"> 0"``, ``">= 0"``, ``"in (-1.5708, 1.5708)"``
        (``""`` when nothing bounds it)."""
        low, high = math.isfinite(self.low), math.isfinite(self.high)
        if low and high:
            return (f"in {'(' if self.low_open else '['}{self.low:g}, "
                    f"{self.high:g}{')' if self.high_open else ']'}")
        if low:
            return f"{'>' if self.low_open else '>='} {self.low:g}"
        if high:
            return f"{'<' if self.high_open else '<='} {self.high:g}"
        return ""


@dataclass(frozen=True)
class Quantity:
    """One named quantity: its JSON key, SI unit (``""``: dimensionless), symbol in
    docs/MODEL.md, one-line meaning, and the interval a real rig's value lies in (None
    where nothing physical bounds it)."""

    key: str
    unit: str
    symbol: str
    meaning: str
    bounds: Bounds | None = None

    @property
    def doc(self) -> str:
        """The meaning with its unit, for messages: ``"barrier surface angle, rad"``."""
        return f"{self.meaning}, {self.unit}" if self.unit else self.meaning

    def check(self, value: object) -> float:
        """``value`` as a float when it is a finite number within the bounds; otherwise
        :class:`~analysis.packed.ParameterError`, one line naming the quantity."""
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ParameterError(f"{self.key} = {value!r}: expected a number")
        if not math.isfinite(value):
            raise ParameterError(f"{self.key} = {value!r}: expected a finite number")
        if self.bounds is not None and value not in self.bounds:
            raise ParameterError(f"{self.key} = {value!r}: must be {self.bounds.words()} "
                                 f"({self.doc})")
        return float(value)


QUANTITIES: dict[str, Quantity] = {}


def _define(key: str, unit: str, symbol: str, meaning: str, bounds: Bounds | None = None) -> str:
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


def check(key: str, value: object) -> float:
    """``value`` of the quantity under ``key``, checked against its registered bounds
    (:meth:`Quantity.check`): where the model, the rig file and the command line validate a
    parameter, the limits are these."""
    return quantity(key).check(value)


_POSITIVE = Bounds(0.0, low_open=True)
_NON_NEGATIVE = Bounds(0.0)

# ---------------------------------------------------------------- the rig (section 3)
m_kg = _define("m_kg", "kg", "m", "pendulum mass", _POSITIVE)
l_m = _define("l_m", "m", "l", "pivot to contact point (shaft length)", _POSITIVE)
L_m = _define("L_m", "m", "L", "effective length", _POSITIVE)
R_m = _define("R_m", "m", "R", "sphere radius", _POSITIVE)
g_m_s2 = _define("g_m_s2", "m/s^2", "g", "gravitational acceleration", _POSITIVE)

# ---------------------------------------------------------------- the baseline (section 7)
omega_rad_s = _define("omega_rad_s", "rad/s", "omega", "small-angle natural frequency sqrt(g/L)",
                      _POSITIVE)
zeta = _define("zeta", "", "zeta", "viscous damping ratio", _NON_NEGATIVE)
K_N_per_m1_5 = _define("K_N_per_m1.5", "N/m^1.5", "K", "Hertz stiffness K = (4/3) E sqrt(R)",
                       _POSITIVE)
E_Pa = _define("E_Pa", "Pa", "E", "effective barrier modulus", _POSITIVE)
mu0_s_per_m = _define("mu0_s_per_m", "s/m", "mu0", "Hunt-Crossley constant", _NON_NEGATIVE)
theta_b_rad = _define("theta_b_rad", "rad", "theta_b", "barrier surface angle",
                      Bounds(-math.pi / 2, math.pi / 2, low_open=True, high_open=True))
theta0_rad = _define("theta0_rad", "rad", "theta_0", "initial angle of a decay record",
                     Bounds(-math.pi, math.pi))
theta_dot0_rad_s = _define("theta_dot0_rad_s", "rad/s", "theta'_0",
                           "initial angular velocity of a decay record")

# ------------------------------------- the constant-restitution alternative (section 4)
e = _define("e", "", "e", "coefficient of restitution of instantaneous impacts",
            Bounds(0.0, 1.0))

# ---------------------------------------------------------------- the drive (section 1)
amplitude_m = _define("amplitude_m", "m", "A", "table drive amplitude", _NON_NEGATIVE)
frequency_hz = _define("frequency_hz", "Hz", "f", "table drive frequency (0: undriven)",
                       _NON_NEGATIVE)

# the drive's timing where a forced record does not give it (no tach, no table channel):
# fitted with the model, its phase at t = 0 and its frequency by the record's own clock
drive_phase_rad = _define("drive_phase_rad", "rad", "phi_0",
                          "drive phase at t = 0, fitted where the record does not give it")
drive_frequency_hz = _define("drive_frequency_hz", "Hz", "f_d",
                             "drive frequency by the record's own clock, fitted where no "
                             "tach gives it", _POSITIVE)

# the drive's names on the command line and in map files (simulate --param, map --vary,
# continuation, a diagram's swept parameter), which the options have always taken: the
# quantities above under shorter names, spelled here once
f_drive_hz = "f_drive_hz"
A_m = "A_m"
COMMAND_LINE_NAMES: dict[str, str] = {f_drive_hz: frequency_hz, A_m: amplitude_m}

# ------------------------------------------------ the nondimensional groups (section 4, eq. 15)
eta = _define("eta", "", "eta", "natural over drive frequency omega / Omega", _POSITIVE)
beta = _define("beta", "", "beta", "drive amplitude over effective length A / L", _NON_NEGATIVE)
mu = _define("mu", "", "mu", "nondimensional Hunt-Crossley constant mu0 l Omega", _NON_NEGATIVE)
gamma = _define("gamma", "", "gamma", "nondimensional stiffness K l^2.5 / (m Omega^2 L^2)",
                _POSITIVE)

# ---------------------------------------------------------------- the causes (section 6)
Tc_N_m = _define("Tc_N_m", "N m", "Tc", "pivot dry-friction torque", _NON_NEGATIVE)
c2_per_rad = _define("c2_per_rad", "1/rad", "c2", "aerodynamic drag coefficient", _NON_NEGATIVE)
n = _define("n", "", "n", "force-penetration exponent", _POSITIVE)
K_n = _define("K_n", "N/m^n", "K_n", "contact stiffness", _POSITIVE)
c_N_s_per_m = _define("c_N_s_per_m", "N s/m", "c", "Kelvin-Voigt contact damping",
                      _NON_NEGATIVE)
h2 = _define("h2", "", "h2", "second-harmonic amplitude ratio", _NON_NEGATIVE)
phi2_rad = _define("phi2_rad", "rad", "phi2", "second-harmonic phase")
eps = _define("eps", "", "eps", "relative error of the stated amplitude",
              Bounds(-1.0, low_open=True))
offset_rad = _define("offset_rad", "rad", "offset", "sensor zero offset")
k3 = _define("k3", "1/rad^2", "k3", "cubic linearity error")
tau_s = _define("tau_s", "s", "tau", "first-order low-pass time constant", _NON_NEGATIVE)
