"""A model's bifurcation diagram against the measured one, step by step, where a lab looks.

The model is simulated through the sweep as the rig ran it (:func:`simulate_sweep`): each
step's drive (its setting, or a drive measured on it), the pendulum's state and the
table's phase carried over from step to step, up and back down, the same settle and the
same dwell.  Each step's simulated dwell is read as the sensor reads (the model's
measurement causes, the record's own noise level, seeded) and judged by the same judge
as the measured record (:func:`analysis.dynamics.measured_regime.judge_record_regime`),
so that period k meets period k and chaos meets chaos on equal terms.  Per step
(:func:`compare_diagram`): whether the regimes agree, and the distance between the
measured and simulated stroboscopic clouds in units of the noise.  Along the sweep,
where the regime changes (a period-doubling, the onset of chaos, any other jump),
located between two steps, on the way up and on the way down (hysteresis shows as the
same change at different places).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.dynamics.continuation import ContinuationError, ContinuationResult, continue_orbits
from analysis.dynamics.measured_regime import judge_record_regime
from analysis.dynamics.period_map import PeriodMap
from analysis.dynamics.regime import Regime
from analysis.dynamics.strobe import StrobeSamples
from analysis.identify.preprocess import noise_and_quantum
from analysis.measurement import MeasurementModel
from analysis.model import Drive, Model, RigParameters
from analysis.packed import P
from analysis.progress import ProgressText
from analysis.simulate import SimulationSettings, simulate_packed
from analysis.sweep.steps import DOWN, UP, Sweep, SweepStep

# The simulated dwell's noise is seeded from this and the step's number: the same
# comparison gives the same figures wherever it runs.
NOISE_SEED = 20_33
RTOL = 1e-9
ATOL = 1e-11
# A cloud's settled part: a periodic step's points after its transient, otherwise the
# second half of the dwell.
UNSETTLED_FRACTION = 0.5
# The regime of a step on which (or after which) the model's simulation went over the top.
OVER_THE_TOP = "over_the_top"


@dataclass(frozen=True)
class SimulatedStep:
    """One step of a sweep as the model ran it: the dwell's samples (time from the dwell's
    start), the drive phase at the dwell's first sample, and the state at its end.  When
    the model's simulation stopped on this step or an earlier one (over the top), no
    samples and ``stopped`` says why."""

    number: int
    drive: Drive
    theta_rad: np.ndarray
    theta_dot_rad_s: np.ndarray
    fs_hz: float
    dwell_phase_rad: float
    end_state: tuple[float, float]
    stopped: str = ""


@dataclass(frozen=True)
class StepPlan:
    """What a simulation needs of one measured step: its drive, its settle and dwell in
    samples at its rate, and its noise (the simulated reading's)."""

    number: int
    drive: Drive
    settle_samples: int
    dwell_samples: int
    fs_hz: float
    noise_rad: float


@dataclass(frozen=True)
class SweepTask:
    """One model through one sweep, as plain data that pickles to any worker: the model's
    fields (:func:`model_fields`), the steps, the start (theta, theta') and drive phase."""

    model: dict[str, Any]
    steps: tuple[StepPlan, ...]
    start: tuple[float, float] = (0.0, 0.0)
    start_phase_rad: float = 0.0


@dataclass(frozen=True)
class JudgedStep:
    """One step's regime and its settled stroboscopic cloud (the angle at 8 drive phases of
    each settled period), with the noise the judgement assumed."""

    number: int
    kind: str  # Regime.kind
    period: int | None
    label: str
    noise_rad: float
    cloud: np.ndarray  # (periods, phases)
    cloud_noise_rad: np.ndarray  # (periods, phases): each point's noise

    @property
    def short(self) -> str:
        """'period-2', 'chaotic', 'quasi-periodic', 'undetermined'."""
        return Regime(self.kind, self.period, self.label).short_name


def model_fields(model: Model) -> dict[str, Any]:
    """The model as plain fields (rig, drive, barrier, causes): what a task carries."""
    return {"rig": model.rig.as_dict(), "drive": asdict(model.drive), "barrier": model.barrier,
            "extensions": {name: dict(values) for name, values in model.extensions.items()}}


def model_from_fields(fields: dict[str, Any]) -> Model:
    """The model :func:`model_fields` gave."""
    return Model(rig=RigParameters(**fields["rig"]), drive=Drive(**fields["drive"]),
                 barrier=fields["barrier"], extensions=fields["extensions"])


def step_drive(model: Model, step: SweepStep, measured: Drive | None = None) -> Drive:
    """The drive the model runs a step with: ``measured`` when given, else the step's
    setting with the model's own drive shape (its second harmonic)."""
    if measured is not None:
        return measured
    return replace(model.drive, amplitude_m=step.amplitude_m, frequency_hz=step.frequency_hz)


def sweep_task(
    model: Model,
    sweep: Sweep,
    measured: Sequence[JudgedStep],
    *,
    drives: Sequence[Drive | None] | None = None,
    start: tuple[float, float] = (0.0, 0.0),
    start_phase_rad: float = 0.0,
) -> SweepTask:
    """The task of running ``model`` through ``sweep`` as the rig ran it: from ``start``
    (theta, theta') at the first settle's start, each step settled for its ``settle_s``
    and dwelt on for its record's length.  ``drives`` gives a step's measured drive (None:
    its setting, :func:`step_drive`); ``measured`` the judged steps, for their noise."""
    if drives is not None and len(drives) != len(sweep.steps):
        raise ValueError(f"{len(drives)} drives for the {len(sweep.steps)} steps of "
                         f"{sweep.source or 'the sweep'}; expected one per step "
                         "(None: its setting)")
    if len(measured) != len(sweep.steps):
        raise ValueError(f"{len(measured)} judged steps for the {len(sweep.steps)} steps of "
                         f"{sweep.source or 'the sweep'}")
    plans = []
    for index, (step, judged) in enumerate(zip(sweep.steps, measured, strict=True)):
        fs = step.record.sample_rate_hz
        plans.append(StepPlan(
            number=step.number,
            drive=step_drive(model, step, None if drives is None else drives[index]),
            settle_samples=round(step.settle_s * fs),
            dwell_samples=int(step.record.time_s.size),
            fs_hz=fs,
            noise_rad=judged.noise_rad,
        ))
    return SweepTask(model_fields(model), tuple(plans), (float(start[0]), float(start[1])),
                     float(start_phase_rad))


def simulate_steps(task: SweepTask) -> tuple[SimulatedStep, ...]:
    """The task's model run through its steps, the state and the drive phase carried from
    each step into the next; when its simulation stops (the pendulum over the top), that
    step and the ones after it have no samples and say so (``SimulatedStep.stopped``)."""
    model = model_from_fields(task.model)
    state, phase = task.start, task.start_phase_rad
    out: list[SimulatedStep] = []
    stopped = ""
    for plan in task.steps:
        if stopped:
            out.append(_no_samples(plan, stopped))
            continue
        fs, total = plan.fs_hz, plan.settle_samples + plan.dwell_samples
        p = replace(model, drive=plan.drive).pack()
        p[P.PHASE0] = phase
        # one sample beyond the dwell's last: the state the next step starts from
        result = simulate_packed(p, state[0], state[1], settings=SimulationSettings(
            duration_s=(total + 1.5) / fs, fs_hz=fs, poincare_phase=None, rtol=RTOL,
            atol=ATOL))
        if result.status != "ok" or result.theta.size < total + 1:
            stopped = f"the model's simulation stopped on step {plan.number} ({result.status})"
            out.append(_no_samples(plan, stopped))
            continue
        omega = plan.drive.Omega_rad_s
        out.append(SimulatedStep(
            number=plan.number,
            drive=plan.drive,
            theta_rad=result.theta[plan.settle_samples:total],
            theta_dot_rad_s=result.theta_dot[plan.settle_samples:total],
            fs_hz=fs,
            dwell_phase_rad=math.remainder(phase + omega * plan.settle_samples / fs,
                                           2.0 * math.pi),
            end_state=(float(result.theta[total]), float(result.theta_dot[total])),
        ))
        state = out[-1].end_state
        phase = math.remainder(phase + omega * total / fs, 2.0 * math.pi)
    return tuple(out)


def _no_samples(plan: StepPlan, stopped: str) -> SimulatedStep:
    empty = np.zeros(0)
    return SimulatedStep(plan.number, plan.drive, empty, empty, plan.fs_hz, math.nan,
                         (math.nan, math.nan), stopped)


def run_sweep_task(task: SweepTask) -> tuple[tuple[SimulatedStep, ...], tuple[JudgedStep, ...]]:
    """Simulate the task's sweep and judge each simulated dwell read as its measured step
    was (the model's measurement causes, the step's noise level, seeded by its number):
    the unit of work a worker runs."""
    model = model_from_fields(task.model)
    simulated = simulate_steps(task)
    judged = []
    for step, plan in zip(simulated, task.steps, strict=True):
        if step.stopped:  # no regime: the model went over the top
            empty = np.zeros((0, 8))
            judged.append(JudgedStep(step.number, OVER_THE_TOP, None, step.stopped,
                                     plan.noise_rad, empty, empty))
            continue
        t = np.arange(step.theta_rad.size) / step.fs_hz
        reading = MeasurementModel(noise_std_rad=plan.noise_rad,
                                   seed=NOISE_SEED * 1000 + step.number).apply(
            t, step.theta_rad, model)
        judged.append(judge_step(step.number, reading, step.fs_hz, plan.noise_rad,
                              tach_indices=None, frequency_hz=step.drive.frequency_hz,
                              phase_rad=step.dwell_phase_rad))
    return simulated, tuple(judged)


def simulate_sweep(
    model: Model,
    sweep: Sweep,
    *,
    drives: Sequence[Drive | None] | None = None,
    start: tuple[float, float] = (0.0, 0.0),
    start_phase_rad: float = 0.0,
) -> tuple[SimulatedStep, ...]:
    """Run ``model`` through ``sweep`` as the rig ran it (see :func:`sweep_task`)."""
    unjudged = [JudgedStep(s.number, "undetermined", None, "", 1.0, np.zeros((0, 8)),
                           np.zeros((0, 8))) for s in sweep.steps]
    return simulate_steps(sweep_task(model, sweep, unjudged, drives=drives, start=start,
                                     start_phase_rad=start_phase_rad))


def judge_measured(sweep: Sweep) -> tuple[JudgedStep, ...]:
    """Each measured step's regime (on its tach, else on its stated drive) and cloud."""
    out = []
    for step in sweep.steps:
        record = step.record
        noise, _ = noise_and_quantum(record.angle_rad)
        tach = record.tach_indices if record.tach_indices.size else None
        out.append(judge_step(step.number, record.angle_rad, record.sample_rate_hz, noise,
                           tach_indices=tach, frequency_hz=step.frequency_hz, phase_rad=0.0))
    return tuple(out)


def judge_step(number: int, angle: np.ndarray, fs_hz: float, noise_rad: float, *,
               tach_indices: np.ndarray | None, frequency_hz: float,
               phase_rad: float) -> JudgedStep:
    """Step ``number``'s regime and stroboscopic points from its dwell's angle, as the
    report and the live sweep judge it; too few drive periods give an undetermined step."""
    try:
        regime, strobe = judge_record_regime(
            np.asarray(angle, dtype=float), fs_hz, noise_rad, tach_indices=tach_indices,
            frequency_hz=frequency_hz, phase_rad=phase_rad)
    except ValueError as error:  # too few drive periods to judge
        empty = np.zeros((0, 8))
        return JudgedStep(number, "undetermined", None, f"undetermined: {error}", noise_rad,
                          empty, empty)
    cloud, cloud_noise = _settled_cloud(regime, strobe, noise_rad)
    return JudgedStep(number, regime.kind, regime.period, regime.label, noise_rad, cloud,
                      cloud_noise)


def _settled_cloud(regime: Regime, strobe: StrobeSamples,
                   noise_rad: float) -> tuple[np.ndarray, np.ndarray]:
    transient = regime.evidence.get("transient_periods") if regime.kind == "periodic" else None
    first = int(transient) if transient is not None else int(len(strobe) * UNSETTLED_FRACTION)
    sigma = np.hypot(noise_rad * strobe.noise_gain, strobe.timing_noise_rad)
    keep = np.all(np.isfinite(strobe.points), axis=1)
    keep[:first] = False
    return strobe.points[keep], sigma[keep]


def cloud_distance(measured: JudgedStep, simulated: JudgedStep) -> float:
    """How far apart two stroboscopic clouds are, in units of the measured points' noise:
    the larger of the two median distances from a point of one cloud to the nearest point
    of the other (RMS over the drive phases, each phase in its own noise).  About 1 when
    the clouds are one orbit seen through the noise; nan when a cloud is empty."""
    a, b = measured.cloud, simulated.cloud
    if a.shape[0] == 0 or b.shape[0] == 0:
        return math.nan
    scale = np.median(measured.cloud_noise_rad, axis=0)
    difference = (a[:, None, :] - b[None, :, :]) / scale
    rms = np.sqrt(np.mean(difference**2, axis=2))
    return float(max(np.median(rms.min(axis=1)), np.median(rms.min(axis=0))))


@dataclass(frozen=True)
class StepAgreement:
    """One step compared: the setting, the two regimes, whether they agree, the distance
    between the clouds in noise units."""

    number: int
    direction: int
    setting: float
    measured: str
    simulated: str
    distance: float

    @property
    def agrees(self) -> bool:
        """Same regime: the same period, or both chaotic (or both quasi-periodic)."""
        return self.measured == self.simulated and self.measured != "undetermined"


@dataclass(frozen=True)
class RegimeChange:
    """A change of regime between two consecutive steps, in the later step's direction."""

    kind: str  # 'period-doubling', 'onset of chaos' or 'jump'
    direction: int
    before: float  # the setting before and after the change, in running order
    after: float
    from_regime: str
    to_regime: str

    @property
    def at(self) -> float:
        """Where the change lies: midway between the two settings."""
        return 0.5 * (self.before + self.after)


def regime_changes(settings: Sequence[float], directions: Sequence[int],
                   regimes: Sequence[str]) -> tuple[RegimeChange, ...]:
    """Every change of regime between consecutive steps, in running order, counted in the
    direction of the later step (the turn at the top belongs to the way down): a period k
    to 2k is a period-doubling, a periodic step followed by a chaotic one the onset of
    chaos, any other change a jump.  Steps whose regime is undetermined are passed over."""
    out = []
    previous: tuple[float, str] | None = None
    for setting, direction, regime in zip(settings, directions, regimes, strict=True):
        if regime == "undetermined":
            continue
        if previous is not None and previous[1] != regime:
            out.append(RegimeChange(_change_kind(previous[1], regime), direction, previous[0],
                                    setting, previous[1], regime))
        previous = (setting, regime)
    return tuple(out)


def _change_kind(before: str, after: str) -> str:
    k_before, k_after = _period(before), _period(after)
    if k_before is not None and k_after == 2 * k_before:
        return "period-doubling"
    if k_before is not None and after == "chaotic":
        return "onset of chaos"
    return "jump"


def _period(short: str) -> int | None:
    return int(short.split("-")[1]) if short.startswith("period-") else None


@dataclass(frozen=True)
class DiagramComparison:
    """A model's diagram against the measured one: per step and where the regime changes."""

    name: str
    parameter: str
    setting_name: str  # 'beta' or 'f [Hz]'
    steps: tuple[StepAgreement, ...]
    measured_changes: tuple[RegimeChange, ...]
    model_changes: tuple[RegimeChange, ...]
    simulated: tuple[SimulatedStep, ...]
    judged: tuple[JudgedStep, ...]

    @property
    def agreeing(self) -> int:
        """How many steps agree on their regime."""
        return sum(step.agrees for step in self.steps)

    def first(self, kind: str, changes: Sequence[RegimeChange]) -> RegimeChange | None:
        """The first change of ``kind`` on the way up (else on the way down)."""
        for direction in (UP, DOWN):
            found = [c for c in changes if c.kind == kind and c.direction == direction]
            if found:
                return found[0]
        return None

    def summary(self) -> str:
        """One line: 'baseline: 6 of 16 steps agree (2 undetermined as measured), the first
        period-doubling at beta 0.083 against 0.099 measured'.  A step whose measured
        regime is undetermined (too few periods to tell chaos from a long period) agrees
        with no model."""
        text = f"{self.name}: {self.agreeing} of {len(self.steps)} steps agree"
        undetermined = sum(step.measured == "undetermined" for step in self.steps)
        if undetermined:
            text += f" ({undetermined} undetermined as measured)"
        for kind in ("period-doubling", "onset of chaos"):
            measured = self.first(kind, self.measured_changes)
            model = self.first(kind, self.model_changes)
            if measured is None and model is None:
                continue
            label = self.setting_name.split(" ")[0]
            text += (f", the first {kind} at "
                     + (f"{label} {model.at:.3g}" if model else "none")
                     + " against "
                     + (f"{measured.at:.3g}" if measured else "none") + " measured")
        return text

    def as_json(self) -> dict[str, Any]:
        """The comparison's figures for the JSON report (no samples)."""
        def change(c: RegimeChange) -> dict[str, Any]:
            return {"kind": c.kind, "direction": "up" if c.direction == UP else "down",
                    "between": [c.before, c.after], "from": c.from_regime, "to": c.to_regime}

        return {
            "model": self.name,
            "parameter": self.parameter,
            "agreeing_steps": self.agreeing,
            "steps": [{"step": s.number, "direction": s.direction, "setting": s.setting,
                       "measured": s.measured, "simulated": s.simulated, "agrees": s.agrees,
                       "distance_in_noise": s.distance} for s in self.steps],
            "measured_changes": [change(c) for c in self.measured_changes],
            "model_changes": [change(c) for c in self.model_changes],
            "summary": self.summary(),
        }


def diagram_setting(sweep: Sweep, step: SweepStep, model: Model) -> float:
    """The step's setting as a diagram shows it: beta = A / L for an amplitude sweep (the
    model's L), the frequency in Hz for a frequency sweep."""
    if sweep.parameter == "amplitude":
        return step.amplitude_m / model.rig.L_m
    return step.frequency_hz


def compare_diagram(
    name: str,
    model: Model,
    sweep: Sweep,
    measured: Sequence[JudgedStep] | None = None,
    *,
    drives: Sequence[Drive | None] | None = None,
    start: tuple[float, float] = (0.0, 0.0),
) -> DiagramComparison:
    """Simulate ``model`` through ``sweep`` and compare its diagram with the measured one
    (``measured``: the sweep's steps judged once by :func:`judge_measured`, shared by every
    model compared)."""
    measured = judge_measured(sweep) if measured is None else tuple(measured)
    task = sweep_task(model, sweep, measured, drives=drives, start=start)
    return assemble(name, model, sweep, measured, run_sweep_task(task))


def compare_diagrams(
    cases: Sequence[tuple[str, Model, Sweep, Sequence[JudgedStep], tuple[float, float]]],
    run_map: Callable[[Callable[[Any], Any], Sequence[Any]], list[Any]] | None = None,
    *,
    drives: Sequence[Sequence[Drive | None] | None] | None = None,
    start_phases: Sequence[float] | None = None,
) -> list[DiagramComparison]:
    """Many models through many sweeps (``cases``: name, model, sweep, its judged steps,
    start), each pair one task; ``run_map`` spreads them over workers
    (``analysis.maps.MapRunner.map``: this process, a local Dask cluster or a scheduler),
    with the same results wherever they ran.  Without it they run here, in order.
    ``drives``: for each case, each step's measured drive (as :func:`sweep_task`; None:
    the steps' settings); ``start_phases``: for each case, the drive's phase at its start
    (default 0)."""
    if drives is not None and len(drives) != len(cases):
        raise ValueError(f"{len(drives)} drive lists for {len(cases)} cases; expected one "
                         "per case (None: the steps' settings)")
    each = drives if drives is not None else [None] * len(cases)
    phases = start_phases if start_phases is not None else [0.0] * len(cases)
    tasks = [sweep_task(model, sweep, measured, drives=case_drives, start=start,
                        start_phase_rad=phase)
             for (_, model, sweep, measured, start), case_drives, phase
             in zip(cases, each, phases, strict=True)]
    results = (run_map(run_sweep_task, tasks) if run_map is not None
               else [run_sweep_task(task) for task in tasks])
    return [assemble(name, model, sweep, tuple(measured), result)
            for (name, model, sweep, measured, _), result in zip(cases, results, strict=True)]


def assemble(
    name: str,
    model: Model,
    sweep: Sweep,
    measured: Sequence[JudgedStep],
    result: tuple[tuple[SimulatedStep, ...], tuple[JudgedStep, ...]],
) -> DiagramComparison:
    """The comparison of a task's result (:func:`run_sweep_task`) with the measured steps."""
    simulated, judged = result
    settings = [diagram_setting(sweep, step, model) for step in sweep.steps]
    directions = [step.direction for step in sweep.steps]
    steps = tuple(
        StepAgreement(step.number, step.direction, setting, m.short, s.short,
                      cloud_distance(m, s))
        for step, setting, m, s in zip(sweep.steps, settings, measured, judged, strict=True)
    )
    return DiagramComparison(
        name=name,
        parameter=sweep.parameter,
        setting_name=q.beta if sweep.parameter == "amplitude" else "f [Hz]",
        steps=steps,
        measured_changes=regime_changes(settings, directions, [m.short for m in measured]),
        model_changes=regime_changes(settings, directions, [s.short for s in judged]),
        simulated=simulated,
        judged=judged,
    )


def model_orbits(
    comparison: DiagramComparison, model: Model, sweep: Sweep, *,
    max_points: int = 400, progress: ProgressText | None = None,
) -> ContinuationResult | None:
    """The model's periodic orbits, stable and unstable, over the sweep's way up: the
    continuation (:mod:`analysis.dynamics.continuation`) of the orbit the simulation
    settled on at the first step it judged periodic, towards the top setting, with the
    branches born at its period-doublings.  None when no simulated step is periodic or
    Newton's method finds no orbit there.  ``progress`` hears of each point found (it may
    raise to stop the continuation)."""
    up = [i for i, s in enumerate(sweep.steps) if s.direction != DOWN]
    first = next((i for i in up if comparison.judged[i].kind == "periodic"), None)
    if first is None:
        return None
    simulated = comparison.simulated[first]
    parameter = q.beta if sweep.parameter == "amplitude" else q.f_drive_hz
    top = max(comparison.steps[i].setting for i in up)
    start = comparison.steps[first].setting
    if top <= start:
        return None
    # the simulated state nearest drive phase 0 near the dwell's end: Newton's guess
    omega = simulated.drive.Omega_rad_s
    phases = (simulated.dwell_phase_rad
              + omega * np.arange(simulated.theta_rad.size) / simulated.fs_hz)
    cycles = np.floor(phases / (2.0 * math.pi))
    crossings = np.flatnonzero(np.diff(cycles) > 0) + 1
    at = int(crossings[-1]) if crossings.size else simulated.theta_rad.size - 1
    guess = np.array([simulated.theta_rad[at], simulated.theta_dot_rad_s[at]])
    period_map = PeriodMap(replace(model, drive=simulated.drive), parameter,
                           comparison.judged[first].period or 1)
    try:
        return continue_orbits(period_map, start, top, guess, max_points=max_points,
                               progress=progress)
    except ContinuationError:
        return None
