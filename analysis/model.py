"""The impact-pendulum model of docs/MODEL.md: parameters, nondimensional form, equations of motion.

The equations are written once, as numba-compiled functions of a packed parameter
vector (layout in :mod:`analysis.packed`) hoisted into a tuple of coefficients, so the
simulator's compiled integrator, the virtual rig and the analysis all integrate exactly the
same physics.  Every term of the superset equation is off (zero) by default; the named
causes of docs/MODEL.md section 6 switch terms on through the registry in
:mod:`analysis.extensions`, never by editing these equations.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace
from types import MappingProxyType

import numba
import numpy as np

from analysis import quantities as q
from analysis.extensions import apply_dynamics, validate_extensions
from analysis.packed import P, ParameterError

G_STANDARD = 9.81


# --------------------------------------------------------------------------- parameters


@dataclass(frozen=True)
class RigParameters:
    """Physical constants of the pendulum and barrier, SI units (docs/MODEL.md section 3)."""

    m_kg: float = 0.0326
    l_m: float = 0.050
    L_m: float = 0.046
    R_m: float = 0.0095
    g_m_s2: float = G_STANDARD
    zeta: float = 0.007
    E_Pa: float = 2.0e6
    mu0_s_per_m: float = 0.75
    theta_b_rad: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):  # each within its registered bounds (the barrier below the pivot)
            q.check(f.name, getattr(self, f.name))

    @property
    def omega_rad_s(self) -> float:
        """Small-angle natural frequency sqrt(g / L)."""
        return math.sqrt(self.g_m_s2 / self.L_m)

    @property
    def K_N_per_m1_5(self) -> float:
        """Hertz stiffness K = (4/3) E sqrt(R), the only contact stiffness motion data identify."""
        return 4.0 / 3.0 * self.E_Pa * math.sqrt(self.R_m)

    def with_stiffness(self, K_N_per_m1_5: float) -> RigParameters:
        """Same rig with the modulus chosen so that K = (4/3) E sqrt(R) takes the given value."""
        q.check(q.K_N_per_m1_5, K_N_per_m1_5)
        return replace(self, E_Pa=3.0 * K_N_per_m1_5 / (4.0 * math.sqrt(self.R_m)))

    def with_values(self, **values: float) -> RigParameters:
        """Copy with some fields replaced (validated); unknown names raise ParameterError."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ParameterError(f"unknown rig parameter(s) {unknown}; known: {sorted(known)}")
        return replace(self, **values)

    def as_dict(self) -> dict[str, float]:
        """Plain dict of the fields, for JSON."""
        return asdict(self)


@dataclass(frozen=True)
class Drive:
    """Horizontal table motion x_t(t) = A sin(Omega t) (+ a second harmonic, see excitation causes).

    ``amplitude_m = 0`` means an unforced experiment.
    """

    amplitude_m: float = 0.0
    frequency_hz: float = 0.0
    h2: float = 0.0
    phi2_rad: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            q.check(f.name, getattr(self, f.name))
        if self.amplitude_m > 0 and self.frequency_hz <= 0:
            raise ParameterError(
                f"frequency_hz = {self.frequency_hz!r}: a drive with amplitude "
                f"{self.amplitude_m} m needs a positive frequency"
            )

    @property
    def Omega_rad_s(self) -> float:
        """Drive angular frequency 2 pi f."""
        return 2.0 * math.pi * self.frequency_hz

    @property
    def period_s(self) -> float:
        """Drive period 1/f (inf when undriven)."""
        return 1.0 / self.frequency_hz if self.frequency_hz > 0 else math.inf

    @property
    def is_forced(self) -> bool:
        """True when the table moves."""
        return self.amplitude_m > 0


# --------------------------------------------------------------------------- nondimensional form


@dataclass(frozen=True)
class Nondimensional:
    """The paper's nondimensional groups (eq. 15), tau = Omega t."""

    eta: float
    beta: float
    mu: float
    gamma: float
    zeta: float = 0.007

    def __post_init__(self) -> None:
        for f in fields(self):
            q.check(f.name, getattr(self, f.name))


def _forming_frequency(frequency_hz: float) -> None:
    if q.check(q.frequency_hz, frequency_hz) <= 0:
        raise ParameterError(f"{q.frequency_hz} must be > 0 to form the nondimensional groups")


def to_nondimensional(rig: RigParameters, drive: Drive) -> Nondimensional:
    """eta = omega/Omega, beta = A/L, mu = mu0 l Omega, gamma = K l^(5/2) / (m Omega^2 L^2)."""
    _forming_frequency(drive.frequency_hz)
    Omega = drive.Omega_rad_s
    gamma = rig.K_N_per_m1_5 * rig.l_m**2.5 / (rig.m_kg * Omega**2 * rig.L_m**2)
    return Nondimensional(
        eta=rig.omega_rad_s / Omega,
        beta=drive.amplitude_m / rig.L_m,
        mu=rig.mu0_s_per_m * rig.l_m * Omega,
        gamma=gamma,
        zeta=rig.zeta,
    )


def from_nondimensional(
    nd: Nondimensional, frequency_hz: float, rig: RigParameters | None = None
) -> tuple[RigParameters, Drive]:
    """Dimensional parameters reproducing ``nd`` at drive frequency ``frequency_hz``.

    m, l, R and g are taken from ``rig`` (default: the paper's rig); L, zeta, E
    (through K, with that R), mu0 and the drive amplitude follow from the groups.
    """
    _forming_frequency(frequency_hz)
    base = rig or RigParameters()
    Omega = 2.0 * math.pi * frequency_hz
    L = base.g_m_s2 / (nd.eta * Omega) ** 2
    K = nd.gamma * base.m_kg * Omega**2 * L**2 / base.l_m**2.5
    dimensional = base.with_values(
        L_m=L, zeta=nd.zeta, mu0_s_per_m=nd.mu / (base.l_m * Omega)
    ).with_stiffness(K)
    return dimensional, Drive(amplitude_m=nd.beta * L, frequency_hz=frequency_hz)


@dataclass(frozen=True)
class PaperCase:
    """One forced case of the paper (docs/MODEL.md section 4 table)."""

    name: str
    frequency_hz: float
    nondimensional: Nondimensional
    experiment: str
    paper_simulation: str

    def dimensional(self, rig: RigParameters | None = None) -> tuple[RigParameters, Drive]:
        """Rig and drive with the paper's nondimensional values (gamma kept, hence K)."""
        return from_nondimensional(self.nondimensional, self.frequency_hz, rig)


def _paper_cases() -> dict[str, PaperCase]:
    low = dict(eta=1.162, mu=0.471, gamma=1.888e4)
    high = dict(eta=0.232, mu=2.356, gamma=755.5)
    table = [
        ("a", 2.0, low, 0.375, "periodic, superharmonics", "periodic, similar spectrum"),
        ("b", 2.0, low, 0.458, "periodic, superharmonics", "-"),
        ("c", 2.0, low, 0.685, "periodic, superharmonics", "periodic, similar spectrum"),
        (
            "d",
            10.0,
            high,
            0.030,
            "period 2 and 3 subharmonics",
            "multiple periodic attractors, period 2",
        ),
        ("e", 10.0, high, 0.064, "subharmonics", "-"),
        ("f", 10.0, high, 0.078, "subharmonics, quasi-periodic content", "-"),
        ("g", 10.0, high, 0.022, "chaotic", "period doubling (periodic), not chaotic"),
        ("h", 10.0, high, 0.114, "chaotic", "chaotic"),
        ("i", 10.0, high, 0.120, "chaotic", "chaotic"),
    ]
    return {
        name: PaperCase(name, f, Nondimensional(beta=beta, **groups), seen, simulated)
        for name, f, groups, beta, seen, simulated in table
    }


PAPER_CASES: MappingProxyType[str, PaperCase] = MappingProxyType(_paper_cases())


def paper_case(name: str) -> PaperCase:
    """The paper's forced case by letter (a..i)."""
    try:
        return PAPER_CASES[name.lower()]
    except KeyError:
        raise ParameterError(
            f"unknown paper case {name!r}; choose one of {', '.join(PAPER_CASES)}"
        ) from None


# --------------------------------------------------------------------------- the model


@dataclass(frozen=True)
class Model:
    """A complete simulation model: rig, drive, barrier in or out, and active extensions.

    ``extensions`` maps a cause name of docs/MODEL.md section 6 to its parameter values;
    :mod:`analysis.extensions` knows how each one acts.
    """

    rig: RigParameters = field(default_factory=RigParameters)
    drive: Drive = field(default_factory=Drive)
    barrier: bool = True
    extensions: MappingProxyType[str, MappingProxyType[str, float]] = field(
        default_factory=lambda: MappingProxyType({})
    )

    def __post_init__(self) -> None:
        frozen = MappingProxyType(
            {name: MappingProxyType(dict(values)) for name, values in dict(self.extensions).items()}
        )
        object.__setattr__(self, "extensions", frozen)
        validate_extensions(self)

    def with_extension(self, name: str, **values: float) -> Model:
        """Copy with one named cause switched on (or its values replaced)."""
        merged = {k: dict(v) for k, v in self.extensions.items()}
        merged[name] = dict(values)
        return replace(self, extensions=MappingProxyType(merged))

    def pack(self) -> np.ndarray:
        """The packed float64 parameter vector (layout ``P``) for the compiled equations."""
        rig, drive = self.rig, self.drive
        p = np.zeros(P.SIZE)
        p[P.OMEGA2] = rig.g_m_s2 / rig.L_m
        p[P.TWO_ZETA_OMEGA] = 2.0 * rig.zeta * rig.omega_rad_s
        p[P.INV_L] = 1.0 / rig.L_m
        p[P.CONTACT_GAIN] = rig.l_m / (rig.m_kg * rig.L_m**2)
        p[P.SHAFT_L] = rig.l_m
        p[P.K] = rig.K_N_per_m1_5
        p[P.EXPONENT] = 1.5
        p[P.MU0] = rig.mu0_s_per_m
        p[P.THETA_B] = rig.theta_b_rad
        p[P.BARRIER] = 1.0 if self.barrier else 0.0
        p[P.OMEGA_DRIVE] = drive.Omega_rad_s
        p[P.A1] = drive.amplitude_m
        p[P.A2] = drive.amplitude_m * drive.h2
        p[P.PHI2] = drive.phi2_rad
        apply_dynamics(self, p)
        p[P.SIN_THETA_B] = math.sin(p[P.THETA_B])
        return p


# --------------------------------------------------------------------------- compiled equations
# The equations of motion are defined once, here, as functions of the coefficient tuple
# below; the compiled integrator (analysis.simulate.integrator) calls these same functions
# for its right-hand side in every region, and the functions of the packed vector further
# down (what the rest of the analysis calls) are these functions too.  Each is compiled
# once and linked into its callers, where LLVM inlines it (numba's own inline="always"
# copied their IR into every call site, which cost a fifth of the integrator's cold
# compile, 55 s to 44 s, for the same speed and bit for bit the same trajectories).
# Neither they nor any caller may set fast-math flags, not even "contract" (fused
# multiply-adds): the integrator's comment on its kernels says why, and without them the
# integrator and these entry points round every term alike.  numba caches a kernel by its
# own file only: after editing these equations, delete analysis/simulate/__pycache__
# (tests/simulate/test_rhs.py fails on a stale cache).

# Positions in the coefficient tuple: the packed vector's entries hoisted into scalars once
# per call, with flags that skip the drive and the general power law when they are off
# (table_acceleration skips the second harmonic itself when its amplitude is 0).
K_OMEGA2, K_TWO_ZETA_OMEGA, K_C2, K_INV_L, K_OMEGA_DRIVE, K_PHASE0 = 0, 1, 2, 3, 4, 5
K_A1, K_A2, K_PHI2, K_GAIN, K_SHAFT, K_STIFFNESS, K_EXPONENT = 6, 7, 8, 9, 10, 11, 12
K_MU0, K_C_VISCOUS, K_SIN_THETA_B, K_CONTACT_ON, K_HERTZ, K_FORCED = 13, 14, 15, 16, 17, 18


@numba.njit(cache=True)
def coefficients(p: np.ndarray, contact: bool) -> tuple[float, ...]:
    """The packed vector as the equations' coefficient tuple; ``contact`` False drops the
    barrier term (the integrator's free-flight region)."""
    forced = p[P.OMEGA_DRIVE] != 0.0 and (p[P.A1] != 0.0 or p[P.A2] != 0.0)
    return (
        p[P.OMEGA2],
        p[P.TWO_ZETA_OMEGA],
        p[P.C2],
        p[P.INV_L],
        p[P.OMEGA_DRIVE],
        p[P.PHASE0],
        p[P.A1],
        p[P.A2],
        p[P.PHI2],
        p[P.CONTACT_GAIN],
        p[P.SHAFT_L],
        p[P.K],
        p[P.EXPONENT],
        p[P.MU0],
        p[P.C_VISCOUS],
        p[P.SIN_THETA_B],
        1.0 if (contact and p[P.BARRIER] != 0.0) else 0.0,
        1.0 if p[P.EXPONENT] == 1.5 else 0.0,
        1.0 if forced else 0.0,
    )


@numba.njit(cache=True)
def indentation(sin_theta: float, k: tuple[float, ...]) -> float:
    """Penetration delta = l (sin theta - sin theta_b) [m], > 0 in contact."""
    return k[K_SHAFT] * (sin_theta - k[K_SIN_THETA_B])


@numba.njit(cache=True)
def barrier_force(sin_theta: float, cos_theta: float, theta_dot: float, k: tuple[float, ...]
                  ) -> float:
    """Barrier force Fc [N] of docs/MODEL.md section 2, generalised by the contact extensions.

    Fc = K delta^n (1 + mu0 deltadot) + c deltadot, clamped at 0 (no adhesion); zero out of
    contact, with the barrier off, or beyond the horizontal (the barrier is at the bottom).
    """
    force = contact_law(sin_theta, cos_theta, theta_dot, k)
    return force if force > 0.0 else 0.0


@numba.njit(cache=True)
def contact_law(sin_theta: float, cos_theta: float, theta_dot: float, k: tuple[float, ...]
                ) -> float:
    """The contact law K delta^n (1 + mu0 deltadot) + c deltadot [N] before the no-adhesion
    clamp (negative where :func:`barrier_force` is 0 in contact); 0 out of contact."""
    if not (k[K_CONTACT_ON] != 0.0 and cos_theta > 0.0):
        return 0.0
    delta = indentation(sin_theta, k)
    if not delta > 0.0:
        return 0.0
    delta_dot = k[K_SHAFT] * cos_theta * theta_dot
    power = delta * math.sqrt(delta) if k[K_HERTZ] != 0.0 else delta ** k[K_EXPONENT]
    force = k[K_STIFFNESS] * power * (1.0 + k[K_MU0] * delta_dot)
    force += k[K_C_VISCOUS] * delta_dot
    return force


# The table's motion, written once: the equations below, the virtual rig's table channel,
# ``simulate``'s recorded table and the fits' regressions all evaluate these two functions.
# Compiled, they take scalars (inside the kernels) or arrays (called from Python).


@numba.njit(cache=True)
def table_displacement(phase: float | np.ndarray, a1_m: float, a2_m: float, phi2_rad: float
                       ) -> float | np.ndarray:
    """The table's displacement x_t [m] at drive phase ``phase`` = Omega t + phase0:
    A1 sin(phase) + A2 sin(2 phase + phi2) (docs/MODEL.md sections 1 and 6; the second
    harmonic is there only with excitation_distortion).  A float or an array of phases."""
    x = a1_m * np.sin(phase)
    if a2_m != 0.0:
        x = x + a2_m * np.sin(2.0 * phase + phi2_rad)
    return x


@numba.njit(cache=True)
def table_acceleration(phase: float | np.ndarray, omega_rad_s: float, a1_m: float, a2_m: float,
                       phi2_rad: float) -> float | np.ndarray:
    """The table's acceleration x_t'' [m/s^2] at drive phase ``phase`` of the motion of
    :func:`table_displacement` at drive angular frequency ``omega_rad_s``:
    -Omega^2 (A1 sin(phase) + 4 A2 sin(2 phase + phi2)).  A float or an array of phases."""
    shape = a1_m * np.sin(phase)
    if a2_m != 0.0:
        shape = shape + 4.0 * a2_m * np.sin(2.0 * phase + phi2_rad)
    return -omega_rad_s * omega_rad_s * shape


@numba.njit(cache=True)
def table_forcing(t: float, cos_theta: float, k: tuple[float, ...]) -> float:
    """-(x_t''(t) / L) cos(theta), the table's push on the pendulum [1/s^2] (x_t'' of
    :func:`table_acceleration`)."""
    w = k[K_OMEGA_DRIVE]
    acc = table_acceleration(w * t + k[K_PHASE0], w, k[K_A1], k[K_A2], k[K_PHI2])
    return -acc * k[K_INV_L] * cos_theta


@numba.njit(cache=True)
def region_acceleration(t: float, theta: float, theta_dot: float, k: tuple[float, ...]
                        ) -> float:
    """theta'' from every term but Coulomb friction: damping, drag, gravity, table, barrier."""
    s = math.sin(theta)
    c = math.cos(theta)
    acc = -k[K_TWO_ZETA_OMEGA] * theta_dot - k[K_C2] * theta_dot * abs(theta_dot)
    acc -= k[K_OMEGA2] * s
    if k[K_FORCED] != 0.0:
        acc += table_forcing(t, c, k)
    force = barrier_force(s, c, theta_dot, k)
    if force > 0.0:
        acc -= k[K_GAIN] * force
    return acc


@numba.njit(cache=True)
def sliding_acceleration(t: float, theta: float, theta_dot: float, k: tuple[float, ...],
                         direction: float, friction: float) -> float:
    """theta'' while sliding in ``direction`` (+1, -1; 0 adds no friction) against the
    Coulomb friction acceleration ``friction`` = Tc / (m L^2)."""
    return region_acceleration(t, theta, theta_dot, k) - direction * friction


@numba.njit(cache=True)
def sliding_direction(t: float, theta: float, theta_dot: float, k: tuple[float, ...],
                      friction: float) -> float:
    """Direction of motion for Coulomb friction: the sign of theta', and at theta' = 0 the
    sign of the other torques, or 0 (stuck) while they stay within the friction torque."""
    if theta_dot > 0.0:
        return 1.0
    if theta_dot < 0.0:
        return -1.0
    acc = region_acceleration(t, theta, 0.0, k)
    if abs(acc) <= friction:
        return 0.0
    return 1.0 if acc > 0.0 else -1.0


# Derivatives of the equation above, for the integrator's sensitivities
# (analysis.simulate.sensitivity): written beside the terms they differentiate, and checked
# against central differences of these same functions (tests/simulate/test_sensitivity.py).


@numba.njit(cache=True)
def barrier_force_partials(sin_theta: float, cos_theta: float, theta_dot: float,
                           k: tuple[float, ...], clamp: bool) -> tuple[float, ...]:
    """Partial derivatives of :func:`barrier_force`: (theta, theta', l, K, n, mu0, c,
    sin theta_b); all zero where the force is (out of contact; clamped, with ``clamp``,
    else those of :func:`contact_law`)."""
    zero = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    if not (k[K_CONTACT_ON] != 0.0 and cos_theta > 0.0):
        return zero
    delta = indentation(sin_theta, k)
    if not delta > 0.0:
        return zero
    shaft = k[K_SHAFT]
    delta_dot = shaft * cos_theta * theta_dot
    n = k[K_EXPONENT]
    if k[K_HERTZ] != 0.0:
        slope_power = math.sqrt(delta)  # delta^(n - 1)
        power = delta * slope_power
        slope_power *= 1.5
    else:
        power = delta**n
        slope_power = n * delta ** (n - 1.0)
    stiffness = k[K_STIFFNESS]
    grip = 1.0 + k[K_MU0] * delta_dot
    force = stiffness * power * grip + k[K_C_VISCOUS] * delta_dot
    if clamp and not force > 0.0:
        return zero
    d_delta = stiffness * slope_power * grip  # dF / d delta
    d_rate = stiffness * power * k[K_MU0] + k[K_C_VISCOUS]  # dF / d deltadot
    return (
        d_delta * shaft * cos_theta - d_rate * shaft * sin_theta * theta_dot,
        d_rate * shaft * cos_theta,
        d_delta * (sin_theta - k[K_SIN_THETA_B]) + d_rate * cos_theta * theta_dot,
        power * grip,
        stiffness * power * math.log(delta) * grip,
        stiffness * power * delta_dot,
        delta_dot,
        -d_delta * shaft,
    )


@numba.njit(cache=True)
def surface_force(cos_theta: float, theta_dot: float, k: tuple[float, ...]) -> float:
    """The limit of :func:`barrier_force` as the penetration falls to 0 from inside
    (theta -> theta_b+): K delta^n vanishes there, Kelvin-Voigt's c deltadot does not.
    Zero for the Hunt-Crossley law, whose force is continuous at the surface."""
    if not (k[K_CONTACT_ON] != 0.0 and cos_theta > 0.0):
        return 0.0
    force = k[K_C_VISCOUS] * k[K_SHAFT] * cos_theta * theta_dot
    return force if force > 0.0 else 0.0


@numba.njit(cache=True)
def acceleration_partials(t: float, theta: float, theta_dot: float, k: tuple[float, ...],
                          direction: float, friction: float, d_p: np.ndarray,
                          clamp: bool = True) -> tuple[float, float, float]:
    """Partial derivatives of :func:`sliding_acceleration`: returns those with respect to
    theta, theta' and t, and writes those with respect to each entry of the packed vector
    into ``d_p`` (indexed by ``P``; THETA_B, which the equation reads only through
    SIN_THETA_B, and BARRIER get 0).  The drive's entries get their derivative whenever
    Omega is not 0, also at a zero amplitude.  Without ``clamp``, those of the equation
    with the unclamped :func:`contact_law` (its smooth continuation past the clamp)."""
    s = math.sin(theta)
    c = math.cos(theta)
    d_p[:] = 0.0
    d_p[P.OMEGA2] = -s
    d_p[P.TWO_ZETA_OMEGA] = -theta_dot
    d_p[P.C2] = -theta_dot * abs(theta_dot)
    d_p[P.COULOMB_ACC] = -direction
    d_theta = -k[K_OMEGA2] * c
    d_theta_dot = -k[K_TWO_ZETA_OMEGA] - 2.0 * k[K_C2] * abs(theta_dot)
    d_t = 0.0
    w = k[K_OMEGA_DRIVE]
    if w != 0.0:
        phase = w * t + k[K_PHASE0]
        second = 2.0 * phase + k[K_PHI2]
        # -x_t'' / Omega^2: the acceleration at unit Omega, negated (exact, as written)
        drive = -table_acceleration(phase, 1.0, k[K_A1], k[K_A2], k[K_PHI2])
        drive_rate = k[K_A1] * math.cos(phase) + 8.0 * k[K_A2] * math.cos(second)  # d / dphase
        gain = w * w * k[K_INV_L]
        d_theta -= gain * drive * s
        d_t = gain * drive_rate * w * c
        d_p[P.INV_L] = w * w * drive * c
        d_p[P.OMEGA_DRIVE] = (2.0 * w * drive + w * w * drive_rate * t) * k[K_INV_L] * c
        d_p[P.PHASE0] = gain * drive_rate * c
        d_p[P.A1] = gain * math.sin(phase) * c
        d_p[P.A2] = 4.0 * gain * math.sin(second) * c
        d_p[P.PHI2] = 4.0 * gain * k[K_A2] * math.cos(second) * c
    force = contact_law(s, c, theta_dot, k)
    if force > 0.0 or (not clamp and force != 0.0):
        f_th, f_om, f_l, f_k, f_n, f_mu0, f_c, f_sb = barrier_force_partials(s, c, theta_dot, k,
                                                                             clamp)
        gain = k[K_GAIN]
        d_theta -= gain * f_th
        d_theta_dot -= gain * f_om
        d_p[P.CONTACT_GAIN] = -force
        d_p[P.SHAFT_L] = -gain * f_l
        d_p[P.K] = -gain * f_k
        d_p[P.EXPONENT] = -gain * f_n
        d_p[P.MU0] = -gain * f_mu0
        d_p[P.C_VISCOUS] = -gain * f_c
        d_p[P.SIN_THETA_B] = -gain * f_sb
    return d_theta, d_theta_dot, d_t


@numba.njit(cache=True)
def penetration(theta: float, p: np.ndarray) -> float:
    """Penetration delta = l (sin theta - sin theta_b) [m] of a packed vector, > 0 in contact."""
    return indentation(math.sin(theta), coefficients(p, True))


@numba.njit(cache=True)
def contact_force(theta: float, theta_dot: float, p: np.ndarray) -> float:
    """Barrier force Fc [N] of a packed vector (see :func:`barrier_force`)."""
    return barrier_force(math.sin(theta), math.cos(theta), theta_dot, coefficients(p, True))


@numba.njit(cache=True)
def smooth_acceleration(t: float, theta: float, theta_dot: float, p: np.ndarray) -> float:
    """theta'' from every term but Coulomb friction (that needs the integrator's stick logic)."""
    return region_acceleration(t, theta, theta_dot, coefficients(p, True))


@numba.njit(cache=True)
def acceleration(t: float, theta: float, theta_dot: float, p: np.ndarray) -> float:
    """theta'' of docs/MODEL.md section 2 plus the active extension terms, while sliding
    (theta' != 0).

    Coulomb friction enters as -Tc/(m L^2) sign(theta'); at theta' = 0 the pendulum
    sticks unless the other torques exceed Tc (:func:`sliding_direction`), which the
    integrator resolves.
    """
    direction = 1.0 if theta_dot > 0.0 else (-1.0 if theta_dot < 0.0 else 0.0)
    return sliding_acceleration(
        t, theta, theta_dot, coefficients(p, True), direction, p[P.COULOMB_ACC]
    )
