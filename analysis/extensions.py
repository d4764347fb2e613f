"""Registry of the named causes of docs/MODEL.md section 6, each an extension of the baseline model.

A cause declares its parameters once (name, unit, default, physical bounds) and
how it acts: a dynamics cause writes its terms into the packed parameter vector
of the compiled equations; a measurement cause transforms the measured angle.
Adding a cause means registering one more ``Cause``; the equations stay as they are.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import numpy as np

from analysis import quantities as q
from analysis.packed import P, ParameterError
from analysis.quantities import quantity

if TYPE_CHECKING:  # types only: analysis.model imports this module to pack its causes
    from analysis.model import Model, RigParameters

NONE = "none"


AT_BOUND = 1e-6  # an estimate this close to a bound (relative to it and the range) sits on it


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter of a cause: its JSON key (a quantity of :mod:`analysis.quantities`,
    which holds its unit and meaning), default, the bounds a fit may explore, and the range
    a real rig can have (None: the bounds)."""

    name: str
    default: float
    lower: float
    upper: float
    plausible: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        entry = quantity(self.name)  # a cause's parameter is a registered quantity
        for value in (self.default, self.lower, self.upper, *(self.plausible or ())):
            entry.check(value)  # a fit explores physical values only: within the registry's

    @property
    def doc(self) -> str:
        """The parameter's meaning and unit, from the registry."""
        return quantity(self.name).doc

    def implausibility(self, value: float) -> str | None:
        """Why ``value`` cannot be a real rig's (outside the plausible range, or on a bound
        of the fit, where the fit stopped rather than found it), or None."""
        if not math.isfinite(value):
            return f"{self.name} = {value!r} is not a number"
        span = self.upper - self.lower
        for bound in (self.lower, self.upper):
            # a bound at the parameter's neutral value (no friction, no lag) is where an
            # absent effect rests, not a stop
            gap = abs(value - bound)
            if bound != self.default and gap <= AT_BOUND * span and gap <= AT_BOUND * abs(bound):
                return f"{self.name} = {value:.4g} sits on the fit's bound {bound:g}"
        if self.plausible is not None:
            low, high = self.plausible
            if not low <= value <= high:
                return (f"{self.name} = {value:.4g} is outside what a real rig can have "
                        f"[{low:g}, {high:g}] ({self.doc})")
        return None


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

    @classmethod
    def of(cls, rig: RigParameters, t: np.ndarray, angle: np.ndarray,
           values: Mapping[str, float], penetration_m: float) -> RecordScale:
        """The scale of a record (uniform times ``t``, angle ``angle``, NaN where excluded)
        under a model's ``values`` (its omega and zeta; K and mu0 when it has them, else
        the rig's), with its contacts' typical largest ``penetration_m``."""
        omega = values[q.omega_rad_s]
        length = rig.g_m_s2 / omega**2  # the pendulum's equivalent length
        return cls(
            amplitude_rad=float(np.nanmax(np.abs(angle))), omega_rad_s=omega,
            zeta=values[q.zeta], duration_s=float(t[-1]), dt_s=float(t[1] - t[0]),
            inertia_kg_m2=rig.m_kg * length**2,
            stiffness=values.get(q.K_N_per_m1_5, rig.K_N_per_m1_5),
            mu0_s_per_m=values.get(q.mu0_s_per_m, rig.mu0_s_per_m),
            penetration_m=penetration_m,
        )


@dataclass(frozen=True)
class ParameterPlan:
    """How one parameter is fitted: start value, finite-difference step, log scale or not.

    ``tie`` (another parameter of the cause, and a coefficient c) makes the fit's coordinate
    of this parameter its value (its log with ``log``) plus c times the other's: moving the
    other at a fixed coordinate moves this one by -c times as much.  Two parameters whose
    effects nearly cancel along a line (an exponent and its stiffness, which together set
    the force at the penetrations a record has) are then fitted along and across that line,
    not both along it; the parameters reported stay the cause's own."""

    start: float
    step: float
    log: bool = False
    tie: tuple[str, float] | None = None


PlanMaker = Callable[[RecordScale], Mapping[str, ParameterPlan]]


def coordinate_matrix(names: Sequence[str], steps: Sequence[float],
                      ties: Sequence[tuple[str, float] | None]) -> np.ndarray:
    """The matrix M that takes a fit's step units u to its parameters' coordinates (each
    value, or its log on a log scale), as offsets from their starts: each parameter's step on
    the diagonal, and for one tied to another (``ParameterPlan.tie``, coefficient c)
    -c times the other's step in the other's column.  A tie to a parameter the fit holds
    fixed has no effect.  The coordinates' covariance is M C M^T for the covariance C of
    u."""
    m = np.diag(np.asarray(steps, dtype=float))
    for i, tie in enumerate(ties):
        if tie is not None and tie[0] in names:
            j = list(names).index(tie[0])
            if ties[j] is not None:
                raise ValueError(f"{names[i]} is tied to {tie[0]}, itself tied: tie a "
                                 f"parameter to an untied one")
            m[i, j] = -tie[1] * steps[j]
    return m


DynamicsHook = Callable[["Model", Mapping[str, float], np.ndarray], None]
# (times, true angle, values, rate at the first sample or None, carry or None) -> measured
# angle; ``carry`` is a dict a caller that measures one signal block after block keeps
# between the blocks, for causes with a state (a filter's output)
MeasurementHook = Callable[[np.ndarray, np.ndarray, Mapping[str, float], float | None,
                            dict[str, float] | None], np.ndarray]


@dataclass(frozen=True)
class Cause:
    """A named way in which the baseline model can be wrong, as an extension of it."""

    name: str
    acts_on: Literal["dynamics", "measurement"]
    parameters: tuple[ParameterSpec, ...]
    doc: str
    dynamics: DynamicsHook | None = None
    measurement: MeasurementHook | None = None
    # the measurement reads a sample through earlier ones (a filter): it must run over
    # contiguous stretches, never over samples from several at once
    measurement_memory: bool = False
    # what a record needs for this cause to show in it (analysis.experiments: "barrier",
    # "drive", "harmonics"); the experiment kind says why it cannot where one is missing
    needs: frozenset[str] = frozenset()
    # how a fit of its parameters starts and steps, scaled to the record at hand (None: at
    # the defaults, steps of 1e-6 of the range)
    plan: PlanMaker | None = None
    # baseline parameters it makes redundant: its own parameters play their part
    replaces: tuple[str, ...] = ()
    # where a measurement acts along the sensor chain (0: the channel's filter of the angle,
    # 1: the transducer's linearity, 2: its zero): several compose in this order, whatever
    # order they entered a model in (docs/MODEL.md section 6)
    measurement_stage: int = 0

    def implausibility(self, values: Mapping[str, float]) -> str | None:
        """Why these fitted values are no explanation a real rig can have, or None."""
        reasons = [r for spec in self.parameters if spec.name in values
                   if (r := spec.implausibility(float(values[spec.name]))) is not None]
        return "; ".join(reasons) or None

    def values(self, given: Mapping[str, float]) -> dict[str, float]:
        """Complete, validated parameter values (defaults filled in)."""
        known = {spec.name: spec for spec in self.parameters}
        unknown = sorted(set(given) - set(known))
        if unknown:
            raise ParameterError(
                f"{self.name}: unknown parameter(s) {unknown}; expected {sorted(known)}"
            )
        out = {}
        for spec in self.parameters:
            value = float(given.get(spec.name, spec.default))
            if not (math.isfinite(value) and spec.lower <= value <= spec.upper):
                raise ParameterError(
                    f"{self.name}.{spec.name} = {value!r}: expected a value in "
                    f"[{spec.lower}, {spec.upper}] ({spec.doc})"
                )
            out[spec.name] = value
        return out


CAUSES: dict[str, Cause] = {}


def register(cause: Cause) -> Cause:
    """Add a cause to the registry (names are unique)."""
    if cause.name in CAUSES or cause.name == NONE:
        raise ValueError(f"cause {cause.name!r} is already registered")
    if (cause.acts_on == "dynamics") != (cause.dynamics is not None) or (
        cause.acts_on == "measurement"
    ) != (cause.measurement is not None):
        raise ValueError(f"cause {cause.name!r}: give exactly the hook matching acts_on")
    CAUSES[cause.name] = cause
    return cause


@dataclass(frozen=True)
class ModelSpec:
    """A model: the baseline of docs/MODEL.md section 2 extended by an ordered tuple of
    named causes (none: the baseline itself).  Hashable; its display ``name`` is derived
    from it (``none``, a cause's name, or causes joined by " + ") and is never parsed."""

    causes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for name in self.causes:
            cause(name)  # a clear error for an unknown name
        if len(set(self.causes)) != len(self.causes):
            raise ParameterError(f"model {self.causes!r}: a cause named twice")

    @classmethod
    def of(cls, *causes: str) -> ModelSpec:
        """The baseline extended by ``causes``, in that order."""
        return cls(tuple(causes))

    @property
    def name(self) -> str:
        """The display name: ``none``, a cause's name, or causes joined by " + "."""
        return " + ".join(self.causes) if self.causes else NONE

    @property
    def is_baseline(self) -> bool:
        """True for the baseline itself (no cause)."""
        return not self.causes

    def plus(self, name: str) -> ModelSpec:
        """This model extended by cause ``name``."""
        return ModelSpec((*self.causes, name))

    def without(self, name: str) -> ModelSpec:
        """This model less cause ``name``."""
        return ModelSpec(tuple(c for c in self.causes if c != name))

    def __str__(self) -> str:
        return self.name


BASELINE = ModelSpec()


def implausibility(model: ModelSpec, values: Mapping[str, float]) -> str | None:
    """Why model ``model``'s fitted values are no explanation a real rig can have, or None."""
    reasons = [r for c in model.causes if (r := cause(c).implausibility(values))]
    return "; ".join(reasons) or None


def cause(name: str) -> Cause:
    """The registered cause called ``name``, with a clear error otherwise."""
    try:
        return CAUSES[name]
    except KeyError:
        raise ParameterError(
            f"unknown cause {name!r}; known: {', '.join(sorted(CAUSES))}"
        ) from None


def validate_extensions(model: Model) -> None:
    """Raise ParameterError for unknown causes or out-of-range values."""
    for name, values in model.extensions.items():
        cause(name).values(values)


def apply_dynamics(model: Model, packed: np.ndarray) -> None:
    """Let every active dynamics cause write its terms into the packed vector."""
    for name, given in model.extensions.items():
        c = cause(name)
        if c.dynamics is not None:
            c.dynamics(model, c.values(given), packed)


def measurement_chain(names: Iterable[str]) -> list[Cause]:
    """The measurement causes among ``names`` in the order the sensor chain applies them
    (``Cause.measurement_stage``: filter, linearity, zero), whatever order they came in."""
    chain = [cause(name) for name in names if name != NONE]
    return sorted((c for c in chain if c.measurement is not None),
                  key=lambda c: c.measurement_stage)


def apply_measurement(model: Model, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The angle a sensor reports for true angle ``theta`` sampled at times ``t``."""
    measured = np.asarray(theta, dtype=float)
    for c in measurement_chain(model.extensions):
        given = model.extensions[c.name]
        measured = c.measurement(np.asarray(t, dtype=float), measured, c.values(given))
    return measured


# --------------------------------------------------------------------------- dynamics causes


def _coulomb(model: Model, v: Mapping[str, float], p: np.ndarray) -> None:
    p[P.COULOMB_ACC] = v[q.Tc_N_m] / (model.rig.m_kg * model.rig.L_m**2)


def _drag(model: Model, v: Mapping[str, float], p: np.ndarray) -> None:
    p[P.C2] = v[q.c2_per_rad]


def _barrier_offset(model: Model, v: Mapping[str, float], p: np.ndarray) -> None:
    p[P.THETA_B] = v[q.theta_b_rad]


def _contact_exponent(model: Model, v: Mapping[str, float], p: np.ndarray) -> None:
    p[P.EXPONENT] = v[q.n]
    p[P.K] = v[q.K_n]


def _kelvin_voigt(model: Model, v: Mapping[str, float], p: np.ndarray) -> None:
    p[P.MU0] = 0.0
    p[P.C_VISCOUS] = v[q.c_N_s_per_m]


def _distortion(model: Model, v: Mapping[str, float], p: np.ndarray) -> None:
    p[P.A2] = model.drive.amplitude_m * v[q.h2]
    p[P.PHI2] = v[q.phi2_rad]


def _amplitude(model: Model, v: Mapping[str, float], p: np.ndarray) -> None:
    p[P.A1] *= 1.0 + v[q.eps]
    p[P.A2] *= 1.0 + v[q.eps]


# --------------------------------------------------------------------------- measurement causes


def _offset(t: np.ndarray, theta: np.ndarray, v: Mapping[str, float],
            theta_dot0: float | None = None, carry: dict[str, float] | None = None,
            ) -> np.ndarray:
    return theta + v[q.offset_rad]


def _nonlinearity(t: np.ndarray, theta: np.ndarray, v: Mapping[str, float],
                  theta_dot0: float | None = None, carry: dict[str, float] | None = None,
                  ) -> np.ndarray:
    # (theta**3 takes numpy's general power, 40 times slower for a negative base)
    return theta + v[q.k3] * (theta * theta * theta)


def _lag(t: np.ndarray, theta: np.ndarray, v: Mapping[str, float],
         theta_dot0: float | None = None, carry: dict[str, float] | None = None,
         ) -> np.ndarray:
    """First-order low pass, exact for an input that is linear between uniform samples.

    (Holding each sample instead, the filter trails a moving angle by tau - dt/2 rather
    than tau: a fit then reads a 5.9 ms lag as 6.4 ms and leaves its residual structured.)
    The filter starts settled: on a constant input, or, given the rate ``theta_dot0`` at
    the first sample, on a ramp, whose lagged copy trails it by tau theta' (a record cut
    out of a moving signal, as a fit's segments are).  With ``carry`` it starts where the
    previous block ended (a live stream).
    """
    if theta.size == 0 or v[q.tau_s] == 0.0:
        return theta
    dt = float(t[1] - t[0]) if t.size >= 2 else (carry or {}).get("dt_s")
    if dt is None:
        return theta
    a = math.exp(-dt / v[q.tau_s])
    ramp = v[q.tau_s] / dt * -math.expm1(-dt / v[q.tau_s])  # tau (1 - a) / dt
    b = [1.0 - ramp, ramp - a]  # y[n] = a y[n-1] + b0 x[n] + b1 x[n-1]
    if carry is not None and "output" in carry:
        state = b[1] * carry["input"] + a * carry["output"]
    else:
        first = theta[0] - (v[q.tau_s] * theta_dot0 if theta_dot0 is not None else 0.0)
        state = first - b[0] * theta[0]
    from scipy.signal import lfilter  # here: scipy.signal takes a second to import

    filtered, _ = lfilter(b, [1.0, -a], theta, zi=[state])
    if carry is not None:
        carry.update(output=float(filtered[-1]), input=float(theta[-1]), dt_s=dt)
    return filtered


def _plan_coulomb(s: RecordScale) -> dict[str, ParameterPlan]:
    # A friction torque of 1e-4 of the largest gravity torque is already a small effect.
    torque = s.inertia_kg_m2 * s.omega_rad_s**2 * max(s.amplitude_rad, 1e-3)
    return {q.Tc_N_m: ParameterPlan(0.0, 1e-4 * torque)}


def _plan_drag(s: RecordScale) -> dict[str, ParameterPlan]:
    # c2 theta'|theta'| equals the viscous term 2 zeta omega theta' at c2 ~ 2 zeta / amplitude.
    return {q.c2_per_rad: ParameterPlan(0.0, 1e-3 * max(s.zeta, 1e-3) / max(s.amplitude_rad, 1e-3))}


def _plan_barrier(s: RecordScale) -> dict[str, ParameterPlan]:
    return {q.theta_b_rad: ParameterPlan(0.0, 1e-5 * max(s.amplitude_rad, 1e-2))}


def _plan_exponent(s: RecordScale) -> dict[str, ParameterPlan]:
    # Fitted as n and the force K_n delta^n at half the record's typical largest penetration
    # (log K_n + n log delta): changing n then leaves the force at the penetrations the
    # record has about where it was.  As (n, K_n) each step of n alone moved that force by a
    # factor delta^dn, and from Hertz's n = 1.5 a fit crept towards a true 2.19 (K_n 5.3e7)
    # and stopped far short of it.
    tie = (q.n, math.log(0.5 * s.penetration_m)) if s.penetration_m > 0 else None
    return {q.n: ParameterPlan(1.5, 1e-3),
            q.K_n: ParameterPlan(s.stiffness, 1e-3, log=True, tie=tie)}


def _plan_kelvin_voigt(s: RecordScale) -> dict[str, ParameterPlan]:
    # Same dissipation per impact as the Hunt-Crossley term at half the largest penetration.
    c = s.stiffness * s.mu0_s_per_m * (0.5 * max(s.penetration_m, 1e-7)) ** 1.5
    return {q.c_N_s_per_m: ParameterPlan(max(c, 1e-6), 1e-3, log=True)}


def _plan_offset(s: RecordScale) -> dict[str, ParameterPlan]:
    return {q.offset_rad: ParameterPlan(0.0, 1e-6 * max(s.amplitude_rad, 1e-2))}


def _plan_nonlinearity(s: RecordScale) -> dict[str, ParameterPlan]:
    return {q.k3: ParameterPlan(0.0, 1e-4)}


def _plan_lag(s: RecordScale) -> dict[str, ParameterPlan]:
    # A sampled first-order lag with tau << dt is the identity to exp(-dt/tau): no gradient
    # there. Start at half a sample period, where the fit can move either way.
    return {q.tau_s: ParameterPlan(0.5 * s.dt_s, 1e-2 * s.dt_s)}


def _plan_distortion(s: RecordScale) -> dict[str, ParameterPlan]:
    return {q.h2: ParameterPlan(0.02, 1e-4), q.phi2_rad: ParameterPlan(0.0, 1e-3)}


def _plan_amplitude(s: RecordScale) -> dict[str, ParameterPlan]:
    return {q.eps: ParameterPlan(0.0, 1e-4)}


register(
    Cause(
        "coulomb_friction",
        "dynamics",
        (ParameterSpec(q.Tc_N_m, 0.0, 0.0, 1.0, (0.0, 0.05)),),
        "Dry friction at the pivot with stiction: + Tc/(m L^2) sign(theta').",
        dynamics=_coulomb,
        plan=_plan_coulomb,
    )
)
register(
    Cause(
        "quadratic_drag",
        "dynamics",
        (ParameterSpec(q.c2_per_rad, 0.0, 0.0, 100.0, (0.0, 50.0)),),
        "Aerodynamic drag: + c2 theta' |theta'|.",
        dynamics=_drag,
        plan=_plan_drag,
    )
)
register(
    Cause(
        "barrier_offset",
        "dynamics",
        (ParameterSpec(q.theta_b_rad, 0.0, -0.5, 0.5, (-0.2, 0.2)),),
        "Barrier surface not at theta = 0: contact while theta > theta_b.",
        dynamics=_barrier_offset,
        needs=frozenset({"barrier"}),
        plan=_plan_barrier,
    )
)
register(
    Cause(
        "contact_exponent",
        "dynamics",
        (
            ParameterSpec(q.n, 1.5, 0.5, 3.0, (0.9, 2.6)),
            ParameterSpec(q.K_n, 1.0e5, 1.0e-3, 1.0e12),
        ),
        "Force-penetration law K_n delta^n instead of Hertz's delta^(3/2).",
        dynamics=_contact_exponent,
        needs=frozenset({"barrier"}),
        plan=_plan_exponent,
        replaces=(q.K_N_per_m1_5,),
    )
)
register(
    Cause(
        "contact_damping_law",
        "dynamics",
        (ParameterSpec(q.c_N_s_per_m, 0.0, 0.0, 1.0e4, (0.0, 1.0e3)),),
        "Kelvin-Voigt contact dissipation K delta^(3/2) + c deltadot instead of Hunt-Crossley.",
        dynamics=_kelvin_voigt,
        needs=frozenset({"barrier"}),
        plan=_plan_kelvin_voigt,
        replaces=(q.mu0_s_per_m,),
    )
)
register(
    Cause(
        "excitation_distortion",
        "dynamics",
        (
            ParameterSpec(q.h2, 0.0, 0.0, 1.0, (0.0, 0.5)),
            ParameterSpec(q.phi2_rad, 0.0, -2 * math.pi, 2 * math.pi),
        ),
        "Table motion with a second harmonic: A h2 sin(2 Omega t + phi2).",
        dynamics=_distortion,
        needs=frozenset({"drive"}),
        plan=_plan_distortion,
    )
)
register(
    Cause(
        "excitation_amplitude",
        "dynamics",
        (ParameterSpec(q.eps, 0.0, -0.9, 9.0, (-0.5, 0.5)),),
        "True table amplitude A (1 + eps).",
        dynamics=_amplitude,
        needs=frozenset({"drive"}),
        plan=_plan_amplitude,
    )
)
register(
    Cause(
        "sensor_offset",
        "measurement",
        (ParameterSpec(q.offset_rad, 0.0, -1.0, 1.0, (-0.3, 0.3)),),
        "Angle sensor zero not at the hanging position: measured = theta + offset.",
        measurement=_offset,
        plan=_plan_offset,
        measurement_stage=2,
    )
)
register(
    Cause(
        "sensor_nonlinearity",
        "measurement",
        (ParameterSpec(q.k3, 0.0, -10.0, 10.0, (-3.0, 3.0)),),
        "Angle sensor linearity error: measured = theta + k3 theta^3.",
        measurement=_nonlinearity,
        plan=_plan_nonlinearity,
        measurement_stage=1,
    )
)
register(
    Cause(
        "sensor_lag",
        "measurement",
        (ParameterSpec(q.tau_s, 0.0, 0.0, 1.0, (0.0, 0.05)),),
        "Angle channel low-pass filtered with time constant tau.",
        measurement=_lag,
        measurement_memory=True,
        needs=frozenset({"harmonics"}),
        plan=_plan_lag,
    )
)
