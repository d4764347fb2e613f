"""Seeded forced records as a lab records them, drawn around the paper's rig and generated
by the reference simulator (never by the project's integrator or virtual rig).

A case holds the drawn truth: the rig, the drive (stated and true), the initial state and
the discarded transient, the measurement chain, the named causes at work, how much of
them shows once the baseline refits its own parameters (a cause that does not show is
never handed out), and the regime of the noiseless motion.  The files written from it
state only what a lab would know: the rig constants m, l, R and g, the stated drive
frequency and amplitude, and the channels time_s, angle_rad, tach and (when the laser is
fitted) table_m.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from analysis.exchange import ExchangeMeta, ExchangeRecord, write_exchange
from reference.cause_sizes import CAUSES, CHOICES, ResponseScale, draw_cause_values
from reference.frozen import frozen
from reference.regime_truth import (
    RegimeTruth,
    attractor_extent,
    find_period,
    judge_regime,
    strobe_times,
)
from reference.simulator import (
    OverTheTopError,
    Pendulum,
    TableMotion,
    simulate_reference,
)
from reference.visibility import SHOWS_OVER_NOISE, Visibility, cause_visibility

FREQUENCIES_HZ = (2.0, 10.0)
# Ranges of beta = A / L giving, over many draws, period-1 and period-2 records at 2 Hz
# (the paper's 0.375-0.685, widened) and period-2, period-k and chaotic records at 10 Hz
# (the paper's 0.022-0.12; above about 0.13 some rigs are driven over the top).
BETA_RANGES = {2.0: (0.3, 0.7), 10.0: (0.02, 0.12)}
TRANSIENT_S = (10.0, 20.0)
ANGLE_NOISE_RAD = (3e-4, 2e-3)
TABLE_NOISE_M = (5e-6, 20e-6)
ADC_BITS = 16
ANGLE_SPAN_RAD = math.pi  # the angle converter spans +-pi/2
TABLE_SPAN_M = 0.1  # a 100 mm laser triangulation sensor, zero at mid range
# Redraws allowed when the regime asked for is not met or a draw goes over the top.
MAX_ATTEMPTS = 40
REGIME_REQUEST = re.compile(r"^(periodic|chaotic|period-k|period-([2-9]|[12][0-9]|3[0-2]))$")
PILOT_S = 10.0  # baseline run that sizes a cause to the response it acts on
# Sizes tried for a cause before the record is given up: the whole plausible range, then
# its largest quarter (the quantile the draw starts from).
SIZE_QUANTILES = (0.0, 0.75)
# A draw asked to be chaotic is first run without its causes over the transient and this
# many drive periods (a third of a 30 s record at 10 Hz); one already periodic there is
# redrawn before the record's full run, its causes' sizing and the twin exponent (at
# 10 Hz most draws settle on an orbit: seed 5202 met chaos at its 8th draw).
PROBE_PERIODS = 96
PROBE_SAMPLES_PER_PERIOD = 50  # for the motion's extent, the scale of "agree"


class CauseHiddenError(RuntimeError):
    """No plausible size of the cause shows in the record: the baseline absorbs it."""


class SettledError(RuntimeError):
    """A draw asked to be chaotic settled on an orbit before the probe's end."""


@dataclass(frozen=True)
class RigTruth:
    """The rig's true constants (docs/MODEL.md section 3 names)."""

    m_kg: float
    l_m: float
    L_m: float
    R_m: float
    g_m_s2: float
    zeta: float
    E_Pa: float
    mu0_s_per_m: float

    @property
    def K_N_per_m1_5(self) -> float:
        """Hertz stiffness K = (4/3) E sqrt(R)."""
        return 4.0 / 3.0 * self.E_Pa * math.sqrt(self.R_m)

    @property
    def omega_rad_s(self) -> float:
        """Small-angle natural frequency sqrt(g / L)."""
        return math.sqrt(self.g_m_s2 / self.L_m)


@dataclass(frozen=True)
class DriveTruth:
    """The drive as stated in the lab's notes and as it truly ran.

    ``phase_rad`` is the true drive phase at the first recorded sample (t = 0); the true
    table amplitude is the stated one unless an excitation cause says otherwise.
    """

    stated_frequency_hz: float
    frequency_hz: float
    stated_amplitude_m: float
    beta: float
    phase_rad: float


@dataclass(frozen=True)
class MeasurementChain:
    """Noise and converter steps of the angle and table channels; the noise's own seed."""

    angle_noise_rad: float
    angle_step_rad: float
    laser: bool
    table_noise_m: float
    table_step_m: float
    noise_seed: int


@dataclass(frozen=True)
class TrueMotion:
    """The noiseless reference run over the record: samples and stroboscopic states."""

    time_s: np.ndarray
    theta_rad: np.ndarray
    theta_dot_rad_s: np.ndarray
    lowpass_rad: np.ndarray | None
    strobe_s: np.ndarray
    strobe_states: np.ndarray


@dataclass(frozen=True)
class ForcedCase:
    """Everything drawn for one forced record: the truth the analysis must find.

    ``causes`` maps each named cause at work (docs/MODEL.md section 6) to its parameters,
    ``effects`` each effect outside the named ones (:mod:`reference.unregistered`);
    ``attempt`` is the sub-seed that met a requested regime (0: the seed itself).
    ``regime_truth.settling`` tells how settled a periodic record's start still is;
    ``visibility`` how much of the cause shows after the baseline refits its own
    parameters (None for a clean record); ``motion`` keeps the noiseless run the regime
    was judged on (not compared).
    """

    seed: int
    attempt: int
    causes: dict[str, dict[str, float]]
    rig: RigTruth
    drive: DriveTruth
    measurement: MeasurementChain
    theta0_rad: float
    theta_dot0_rad_s: float
    transient_s: float
    duration_s: float
    sample_rate_hz: float
    regime_truth: RegimeTruth
    visibility: Visibility | None = None
    motion: TrueMotion | None = field(default=None, compare=False, repr=False)
    effects: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def cause(self) -> str:
        """The single cause at work, or "none"."""
        if not self.causes:
            return "none"
        if len(self.causes) > 1:
            raise ValueError(f"several causes at work: {sorted(self.causes)}")
        return next(iter(self.causes))

    @property
    def regime(self) -> str:
        """periodic (period 1), period-k, chaotic, quasi-periodic or unsettled."""
        return self.regime_truth.regime

    @property
    def period(self) -> int | None:
        """Period in drive periods, None when not periodic."""
        return self.regime_truth.period

    @property
    def lyapunov_per_s(self) -> float | None:
        """Largest Lyapunov exponent, computed when no period is found."""
        return self.regime_truth.lyapunov_per_s

    def pendulum(self) -> Pendulum:
        """The true dynamics: the rig with every dynamics cause (and effect) at work."""
        return true_pendulum(self.rig, self.causes, self.effects)

    def table(self) -> TableMotion:
        """The true table motion, phase counted from the first recorded sample."""
        return true_table(self.drive, self.causes, self.effects)

    def time_s(self) -> np.ndarray:
        """Sample times of the record, 0 at the first sample."""
        return np.arange(round(self.duration_s * self.sample_rate_hz)) / self.sample_rate_hz


@dataclass(frozen=True)
class GeneratedRecord:
    """The channels as the lab records them, and the noiseless true angle beside them."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    table_m: np.ndarray | None
    tach: np.ndarray
    true_angle_rad: np.ndarray


def draw_rig(rng: np.random.Generator) -> RigTruth:
    """A rig around the paper's, drawn from ``rng``."""
    return RigTruth(
        m_kg=0.0326 * rng.uniform(0.97, 1.03),
        l_m=0.050 * rng.uniform(0.98, 1.02),
        L_m=rng.uniform(0.040, 0.056),
        R_m=0.0095 * rng.uniform(0.98, 1.02),
        g_m_s2=9.81,
        zeta=rng.uniform(0.004, 0.012),
        E_Pa=rng.uniform(1.0e6, 4.0e6),
        mu0_s_per_m=rng.uniform(0.4, 1.2),
    )


def true_pendulum(rig: RigTruth, causes: dict[str, dict[str, float]],
                  effects: dict[str, dict[str, float]] | None = None) -> Pendulum:
    """The rig's pendulum with the dynamics causes of ``causes`` (and of ``effects``)
    applied."""
    values: dict[str, float] = {
        "m_kg": rig.m_kg, "l_m": rig.l_m, "L_m": rig.L_m, "g_m_s2": rig.g_m_s2,
        "zeta": rig.zeta, "K_n": rig.K_N_per_m1_5, "mu0_s_per_m": rig.mu0_s_per_m,
    }
    if "coulomb_friction" in causes:
        values["Tc_N_m"] = causes["coulomb_friction"]["Tc_N_m"]
    if "quadratic_drag" in causes:
        values["c2_per_rad"] = causes["quadratic_drag"]["c2_per_rad"]
    if "barrier_offset" in causes:
        values["theta_b_rad"] = causes["barrier_offset"]["theta_b_rad"]
    if "contact_exponent" in causes:
        values["n"] = causes["contact_exponent"]["n"]
        values["K_n"] = causes["contact_exponent"]["K_n"]
    if "contact_damping_law" in causes:  # Kelvin-Voigt replaces Hunt-Crossley's damping
        values["mu0_s_per_m"] = 0.0
        values["c_N_s_per_m"] = causes["contact_damping_law"]["c_N_s_per_m"]
    effects = effects or {}
    values["c3_per_s2"] = effects.get("pivot_hairspring", {}).get("c3_per_s2", 0.0)
    values["K_drift_per_s"] = effects.get("barrier_warming", {}).get("K_drift_per_s", 0.0)
    return Pendulum(**values)


def true_table(drive: DriveTruth, causes: dict[str, dict[str, float]],
               effects: dict[str, dict[str, float]] | None = None) -> TableMotion:
    """The table's true motion with the excitation causes of ``causes`` (and the
    amplifier's wandering gain of ``effects``) applied."""
    eps = causes.get("excitation_amplitude", {}).get("eps", 0.0)
    distortion = causes.get("excitation_distortion", {})
    wander = (effects or {}).get("drive_gain_wander", {})
    return TableMotion(
        amplitude_m=drive.stated_amplitude_m * (1.0 + eps),
        frequency_hz=drive.frequency_hz,
        phase_rad=drive.phase_rad,
        h2=distortion.get("h2", 0.0),
        phi2_rad=distortion.get("phi2_rad", 0.0),
        am_depth=wander.get("depth", 0.0),
        am_frequency_hz=wander.get("frequency_hz", 0.0),
        am_phase_rad=wander.get("phase_rad", 0.0),
    )


def with_motion(case: ForcedCase) -> ForcedCase:
    """The case with its noiseless motion simulated (a frozen draw is stored without it)."""
    return replace(case, motion=simulate_true_motion(case))


@frozen(restore=with_motion)
def draw_forced_case(
    seed: int,
    cause: str | tuple[str, ...] | None = None,
    *,
    frequency_hz: float | None = None,
    regime: str | None = None,
    duration_s: float = 60.0,
    sample_rate_hz: float = 1000.0,
    laser: bool | None = None,
) -> ForcedCase:
    """A random forced case from ``numpy.random.default_rng(seed)``.

    ``cause``, ``frequency_hz`` and ``laser`` fix those draws (the others stay as the seed
    makes them); ``cause`` may be several causes at once, each drawn at a size that shows
    on its own.  ``regime`` ("periodic" for period 1, "period-k" for any subharmonic,
    "period-2".."period-32", "chaotic") is met by drawing again from the sub-seeds
    (seed, 1), (seed, 2), ... until the noiseless motion has it; draws driven over the
    top are redrawn the same way.  A cause is drawn at a size that shows after the
    baseline refits its own parameters (``case.visibility``): one that does not is drawn
    again from the largest part of its plausible range, and then the record is redrawn.
    """
    _check_request(seed, cause, frequency_hz, regime, duration_s, sample_rate_hz, laser)
    seen: dict[str, int] = {}
    last_hidden = ""
    for attempt in range(MAX_ATTEMPTS):
        rng = np.random.default_rng(seed if attempt == 0 else [seed, attempt])
        try:
            case = _draw_once(rng, seed, attempt, cause, frequency_hz, duration_s,
                              sample_rate_hz, laser, probe=regime == "chaotic")
        except OverTheTopError:
            seen["over the top"] = seen.get("over the top", 0) + 1
            continue
        except CauseHiddenError as hidden:
            seen["cause hidden"] = seen.get("cause hidden", 0) + 1
            last_hidden = str(hidden)
            continue
        except SettledError:
            seen["periodic at the probe"] = seen.get("periodic at the probe", 0) + 1
            continue
        if regime is None or _regime_matches(case.regime_truth, regime):
            return case
        seen[case.regime] = seen.get(case.regime, 0) + 1
    raise RuntimeError(
        f"seed {seed}: no draw met regime={regime!r} (cause={cause!r}, "
        f"frequency_hz={frequency_hz!r}) in {MAX_ATTEMPTS} attempts; drew {seen}"
        + (f"; last: {last_hidden}" if last_hidden else "")
    )


def draw_pair(seed: int) -> tuple[str, str]:
    """Two different registered causes drawn from ``seed`` (in name order)."""
    rng = np.random.default_rng([seed, 2])
    return tuple(sorted(str(c) for c in rng.choice(CAUSES, 2, replace=False)))


def _check_request(
    seed: int,
    cause: str | tuple[str, ...] | None,
    frequency_hz: float | None,
    regime: str | None,
    duration_s: float,
    sample_rate_hz: float,
    laser: bool | None,
) -> None:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed = {seed!r}: expected a non-negative integer")
    several = isinstance(cause, tuple)
    for name in (cause if several else () if cause is None else (cause,)):
        if name not in (CAUSES if several else CHOICES):
            raise ValueError(f"cause = {cause!r}: expected one of {', '.join(CHOICES)}"
                             + (" (several: no 'none')" if several else ""))
    if several and len(set(cause)) != len(cause):
        raise ValueError(f"cause = {cause!r}: a cause given twice")
    if frequency_hz is not None and frequency_hz not in FREQUENCIES_HZ:
        raise ValueError(f"frequency_hz = {frequency_hz!r}: expected one of {FREQUENCIES_HZ}")
    if regime is not None and not REGIME_REQUEST.match(regime):
        raise ValueError(
            f"regime = {regime!r}: expected 'periodic', 'chaotic', 'period-k' or "
            "'period-2' .. 'period-32'"
        )
    for name, value in (("duration_s", duration_s), ("sample_rate_hz", sample_rate_hz)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise ValueError(f"{name} = {value!r}: expected a positive number")
    if duration_s * sample_rate_hz < 2:
        raise ValueError(f"duration_s * sample_rate_hz = {duration_s * sample_rate_hz}: "
                         "a record needs at least 2 samples")
    if laser is not None and not isinstance(laser, bool):
        raise ValueError(f"laser = {laser!r}: expected True, False or None")


def _regime_matches(truth: RegimeTruth, wanted: str) -> bool:
    if wanted == "period-k":
        return truth.period is not None and truth.period >= 2
    return truth.regime == wanted


def _draw_once(
    rng: np.random.Generator,
    seed: int,
    attempt: int,
    cause: str | tuple[str, ...] | None,
    frequency_hz: float | None,
    duration_s: float,
    sample_rate_hz: float,
    laser: bool | None,
    probe: bool = False,
) -> ForcedCase:
    """One draw; the given choices replace their draws so that the rest stays the same.
    ``probe``: raise SettledError when the draw's baseline settles on an orbit early."""
    drawn_cause = str(CHOICES[rng.integers(len(CHOICES))])
    drawn_frequency = float(FREQUENCIES_HZ[rng.integers(len(FREQUENCIES_HZ))])
    drawn_laser = bool(rng.random() < 0.5)
    cause = drawn_cause if cause is None else cause
    stated_frequency = drawn_frequency if frequency_hz is None else float(frequency_hz)
    laser = drawn_laser if laser is None else laser
    rig_rng, drive_rng, start_rng, measure_rng, cause_rng = rng.spawn(5)

    rig = draw_rig(rig_rng)
    beta_drawn = drive_rng.uniform(*BETA_RANGES[stated_frequency])
    stated_amplitude = round(beta_drawn * rig.L_m, 5)  # the shaker is set to 0.01 mm
    detuning = drive_rng.uniform(1e-4, 5e-4) * float(drive_rng.choice([-1.0, 1.0]))
    drive = DriveTruth(
        stated_frequency_hz=stated_frequency,
        frequency_hz=stated_frequency * (1.0 + detuning),
        stated_amplitude_m=stated_amplitude,
        beta=stated_amplitude / rig.L_m,
        phase_rad=drive_rng.uniform(0.0, 2.0 * math.pi),
    )
    transient = start_rng.uniform(*TRANSIENT_S)
    theta0 = start_rng.uniform(-0.2, 0.0)
    theta_dot0 = start_rng.uniform(-1.0, 1.0)
    step_angle = ANGLE_SPAN_RAD / 2**ADC_BITS
    measurement = MeasurementChain(
        angle_noise_rad=measure_rng.uniform(*ANGLE_NOISE_RAD),
        angle_step_rad=step_angle,
        laser=laser,
        table_noise_m=measure_rng.uniform(*TABLE_NOISE_M),
        table_step_m=TABLE_SPAN_M / 2**ADC_BITS,
        noise_seed=int(measure_rng.integers(2**63)),
    )
    case = ForcedCase(
        seed=seed, attempt=attempt, causes={}, rig=rig, drive=drive,
        measurement=measurement, theta0_rad=theta0, theta_dot0_rad_s=theta_dot0,
        transient_s=transient, duration_s=float(duration_s), sample_rate_hz=float(sample_rate_hz),
        regime_truth=RegimeTruth("unsettled", None, None, None),
    )
    if probe and _settles_early(case):
        raise SettledError(f"seed {seed}, draw {attempt}: periodic at the probe")
    if cause == "none":
        motion = simulate_true_motion(case)
    else:
        case, motion = _with_visible_causes(
            case, cause if isinstance(cause, tuple) else (cause,), cause_rng)
    extent = attractor_extent(motion.theta_rad, motion.theta_dot_rad_s)
    truth = judge_regime(case.pendulum(), case.table(), motion.strobe_s, motion.strobe_states,
                         extent)
    return replace(case, regime_truth=truth, motion=motion)


def _settles_early(case: ForcedCase) -> bool:
    """Whether the case's motion without causes repeats with a period <= 32 over the second
    half of its first PROBE_PERIODS drive periods (the truth's own test, regime_truth)."""
    table = true_table(case.drive, {})
    end_s = min(case.duration_s, PROBE_PERIODS / case.drive.frequency_hz)
    strobe_s = strobe_times(table, 0.0, end_s)
    grid_s = np.linspace(0.0, end_s, round(PROBE_PERIODS * PROBE_SAMPLES_PER_PERIOD) + 1)
    times = np.union1d(grid_s, strobe_s)
    run = simulate_reference(true_pendulum(case.rig, {}), table, case.theta0_rad,
                             case.theta_dot0_rad_s, times, t_start_s=-case.transient_s,
                             rtol=1e-9, atol=1e-11)
    at_strobe = np.searchsorted(times, strobe_s)
    points = np.column_stack([run.theta_rad[at_strobe], run.theta_dot_rad_s[at_strobe]])
    return find_period(points, attractor_extent(run.theta_rad, run.theta_dot_rad_s)) is not None


def _with_visible_causes(
    case: ForcedCase, causes: tuple[str, ...], rng: np.random.Generator
) -> tuple[ForcedCase, TrueMotion]:
    """The case with each of ``causes`` drawn at a size that shows on its own after the
    baseline refits its own parameters (SIZE_QUANTILES: the plausible range, then its
    largest quarter), and its motion; CauseHiddenError when no size tried shows."""
    rig, drive = case.rig, case.drive
    scale = _pilot_scale(rig, drive, case.theta0_rad, case.theta_dot0_rad_s, case.transient_s)
    drawn: dict[str, dict[str, float]] = {}
    for cause in causes:
        tried = []
        for at_least in SIZE_QUANTILES:
            values = draw_cause_values(
                rng, cause, scale, m_kg=rig.m_kg, l_m=rig.l_m, L_m=rig.L_m, zeta=rig.zeta,
                omega_rad_s=rig.omega_rad_s, K_N_per_m1_5=rig.K_N_per_m1_5,
                mu0_s_per_m=rig.mu0_s_per_m, noise_rad=case.measurement.angle_noise_rad,
                gravity_torque_N_m=rig.m_kg * rig.g_m_s2 * rig.L_m, at_least=at_least,
            )
            sized = replace(case, causes={cause: values})
            motion = simulate_true_motion(sized)
            visibility = visibility_of(sized, motion)
            if visibility.shows:
                drawn[cause] = values
                break
            tried.append(f"{visibility.visible_over_noise:.2g}")
        else:
            raise CauseHiddenError(
                f"{cause} does not show in this record at any plausible size: the baseline's "
                f"refit leaves {', '.join(tried)} x the noise (needs {SHOWS_OVER_NOISE:g})"
            )
    if len(causes) > 1:
        sized = replace(case, causes=drawn)
        motion = simulate_true_motion(sized)
        visibility = visibility_of(sized, motion)
    return replace(sized, visibility=visibility), motion


def visibility_of(case: ForcedCase, motion: TrueMotion) -> Visibility:
    """How much of the case's causes shows in its noiseless reading after the baseline (the
    rig's values, the stated table as a pure sine) refits its own parameters."""
    return cause_visibility(
        true_pendulum(case.rig, {}), true_table(case.drive, {}), motion.time_s,
        motion.theta_rad, motion.theta_dot_rad_s,
        sensor_reading(motion, case.causes, case.effects),
        case.measurement.angle_noise_rad,
    )


def _pilot_scale(
    rig: RigTruth, drive: DriveTruth, theta0: float, theta_dot0: float, transient_s: float
) -> ResponseScale:
    """The baseline's response over the second half of a short run from the case's start:
    what a cause's size is scaled to."""
    pendulum = true_pendulum(rig, {})
    times = np.linspace(-transient_s + PILOT_S / 2, -transient_s + PILOT_S, 2001)
    run = simulate_reference(pendulum, true_table(drive, {}), theta0, theta_dot0, times,
                             t_start_s=-transient_s, rtol=1e-8, atol=1e-10)
    speed = np.abs(run.theta_dot_rad_s)
    entries = [e for e in run.events_of("contact_entry") if e.t_s >= times[0]]
    amplitude = float(np.max(np.abs(run.theta_rad)))
    if entries:
        impact = float(np.median([rig.l_m * math.cos(e.theta_rad) * e.theta_dot_rad_s
                                  for e in entries]))
    else:  # no impact yet: the speed a swing of this size would bring
        impact = rig.l_m * rig.omega_rad_s * amplitude
    return ResponseScale(
        amplitude_rad=amplitude,
        mean_speed_rad_s=float(np.mean(speed)),
        mean_square_speed=float(np.mean(speed**2)),
        mean_cube_speed=float(np.mean(speed**3)),
        impact_speed_m_s=impact,
    )


def simulate_true_motion(case: ForcedCase) -> TrueMotion:
    """The noiseless motion over the record, from the drawn start after the transient."""
    time_s = case.time_s()
    table = case.table()
    strobe_s = strobe_times(table, 0.0, float(time_s[-1]))
    times = np.union1d(time_s, strobe_s)
    lag = case.causes.get("sensor_lag", {}).get("tau_s")
    run = simulate_reference(case.pendulum(), table, case.theta0_rad, case.theta_dot0_rad_s,
                             times, t_start_s=-case.transient_s, lowpass_tau_s=lag)
    at_samples = np.searchsorted(times, time_s)
    at_strobe = np.searchsorted(times, strobe_s)
    return TrueMotion(
        time_s=time_s,
        theta_rad=run.theta_rad[at_samples],
        theta_dot_rad_s=run.theta_dot_rad_s[at_samples],
        lowpass_rad=None if run.lowpass_rad is None else run.lowpass_rad[at_samples],
        strobe_s=strobe_s,
        strobe_states=np.column_stack([run.theta_rad[at_strobe], run.theta_dot_rad_s[at_strobe]]),
    )


def sensor_reading(motion: TrueMotion, causes: dict[str, dict[str, float]],
                   effects: dict[str, dict[str, float]] | None = None) -> np.ndarray:
    """The angle sensor's noiseless output: the (low-passed) angle, its cubic linearity
    error, its zero offset; and the sensor effects of ``effects``: a gain and a zero that
    drift linearly over the record, an interference line."""
    angle = motion.theta_rad if motion.lowpass_rad is None else motion.lowpass_rad
    k3 = causes.get("sensor_nonlinearity", {}).get("k3", 0.0)
    offset = causes.get("sensor_offset", {}).get("offset_rad", 0.0)
    reading = angle + k3 * angle**3 + offset
    effects = effects or {}
    t = motion.time_s
    along = (t - t[0]) / max(float(t[-1] - t[0]), 1e-300)  # 0 at the start, 1 at the end
    reading = reading * (1.0 + effects.get("sensor_gain_drift", {}).get("gain_change", 0.0)
                         * along)
    reading = reading + effects.get("sensor_zero_drift", {}).get("offset_change_rad", 0.0) * along
    hum = effects.get("sensor_hum")
    if hum:
        reading = reading + hum["amplitude_rad"] * np.sin(
            2.0 * math.pi * hum["frequency_hz"] * t + hum["phase_rad"])
    return reading


def quantise(values: np.ndarray, step: float) -> np.ndarray:
    """A 16-bit converter centred on 0 with the given step; saturates at its rails."""
    half = 2 ** (ADC_BITS - 1)
    return np.clip(np.round(values / step), -half, half - 1) * step


def tach_pulses(time_s: np.ndarray, table: TableMotion, delay_s: float = 0.0) -> np.ndarray:
    """1 on the first sample at or after each instant the true drive phase passes 2 pi k
    (``delay_s`` later: a tach whose pulse lags the table)."""
    tach = np.zeros(time_s.size, dtype=np.int64)
    instants = strobe_times(table, float(time_s[0]), float(time_s[-1])) + delay_s
    instants = instants[instants <= time_s[-1]]
    tach[np.searchsorted(time_s, instants, side="left")] = 1
    return tach


def generate(case: ForcedCase) -> GeneratedRecord:
    """The record's channels: noise and converter steps as the case says, seeded."""
    motion = case.motion if case.motion is not None else simulate_true_motion(case)
    chain = case.measurement
    rng = np.random.default_rng(chain.noise_seed)
    angle_noise = rng.normal(0.0, chain.angle_noise_rad, motion.time_s.size)
    table_noise = rng.normal(0.0, chain.table_noise_m, motion.time_s.size)
    heavy = case.effects.get("heavy_tailed_noise")
    if heavy:  # Student's t, scaled to the same median absolute deviation as the normal
        t_noise = rng.standard_t(heavy["dof"], motion.time_s.size)
        scale = 0.6744897501960817 / float(np.median(np.abs(rng.standard_t(heavy["dof"],
                                                                          200_001))))
        angle_noise = chain.angle_noise_rad * scale * t_noise
    reading = sensor_reading(motion, case.causes, case.effects)
    angle = quantise(reading + angle_noise, chain.angle_step_rad)
    table = case.table()
    table_m = None
    if chain.laser:
        table_m = quantise(table.displacement(motion.time_s) + table_noise, chain.table_step_m)
    return GeneratedRecord(
        time_s=motion.time_s,
        angle_rad=angle,
        table_m=table_m,
        tach=tach_pulses(motion.time_s, table,
                         case.effects.get("tach_delay", {}).get("delay_s", 0.0)),
        true_angle_rad=motion.theta_rad,
    )


def write_forced_case(
    case: ForcedCase, directory: str | Path, name: str = "record", *, overwrite: bool = False
) -> Path:
    """Write NAME.csv and NAME.json into ``directory``; returns the CSV's path.

    The JSON states the rig's m, l, R, g and the stated drive, nothing else of the truth.
    """
    csv_path = Path(directory) / f"{name}.csv"
    if not overwrite:
        for path in (csv_path, csv_path.with_suffix(".json")):
            if path.exists():
                raise FileExistsError(f"{path}: exists; pass overwrite=True to replace it")
    record = generate(case)
    meta = ExchangeMeta(
        experiment="forced",
        rig={"m_kg": case.rig.m_kg, "l_m": case.rig.l_m, "R_m": case.rig.R_m,
             "g": case.rig.g_m_s2},
        drive={"frequency_hz": case.drive.stated_frequency_hz,
               "amplitude_m": case.drive.stated_amplitude_m},
    )
    exchange = ExchangeRecord(time_s=record.time_s, angle_rad=record.angle_rad, meta=meta,
                              table_m=record.table_m, tach=record.tach)
    write_exchange(csv_path, exchange, overwrite=overwrite)
    return csv_path
