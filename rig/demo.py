"""The end-to-end demonstration: the virtual rig with a hidden physical effect, recorded and
explained by the same drivers, procedures and analysis a real rig uses, into a report folder.

The virtual rig runs over its real protocols (serial DAQ on a pty, amplifier on
Modbus TCP), faster than real time, with one named cause of docs/MODEL.md section 6
switched on that the baseline model lacks.  The demo records a free decay, an
impact decay and a forced amplitude sweep at 10 Hz (up and down); identifies L,
zeta, K and mu0 with intervals; runs the discrepancy analysis on every record
(without being told the cause); judges the regime of every sweep step; and
draws the measured bifurcation diagram against the one simulated with the
identified model.  Only at the end is the hidden cause revealed, next to what
the analysis named.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

from rig.config import RigConfig, load_config

Progress = Callable[[str], None]

NONE = "none"
DEFAULT_CAUSE = "coulomb_friction"
# Pivot friction that takes about 5 mrad off the swing per cycle: as much as the viscous
# damping does at 0.12 rad, so the free decay's envelope turns visibly straight, while
# a release at 0.15 rad still gives a decay of some twenty cycles.
DEFAULT_CAUSE_VALUES: Mapping[str, float] = MappingProxyType({"Tc_N_m": 2.0e-5})
RECORDINGS = "recordings"
FIGURES = "figures"
ANALYSIS = "analysis"  # one discrepancy-analysis page (Markdown, JSON, figures) per record
REPORT_NAME = "report.md"


class DemoError(RuntimeError):
    """The demo cannot run or cannot go on; the message says what was wrong."""


@dataclass(frozen=True)
class HiddenCause:
    """The effect switched on in the virtual rig (``none``: the baseline model is exact)."""

    name: str
    values: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))

    def describe(self) -> str:
        """'coulomb_friction (Tc_N_m = 2e-05)' or 'none'."""
        if self.name == NONE:
            return NONE
        inner = ", ".join(f"{k} = {v:g}" for k, v in self.values.items())
        return f"{self.name} ({inner})"


def hidden_cause(name: str, given: Mapping[str, float] | None = None) -> HiddenCause:
    """Validate a cause name and its parameter values against the registry (defaults filled in)."""
    from analysis.extensions import cause
    from analysis.model import ParameterError

    given = dict(given or {})
    if name == NONE:
        if given:
            raise DemoError(f"--cause none takes no parameters (got {sorted(given)})")
        return HiddenCause(NONE)
    try:
        values = cause(name).values(given)
    except ParameterError as error:
        raise DemoError(str(error)) from None
    return HiddenCause(name, MappingProxyType(values))


@dataclass(frozen=True)
class DemoSettings:
    """How much the demo records and simulates.  Durations are in rig time (the virtual
    rig runs ``virtual_speed`` times faster than the wall clock)."""

    name: str
    sample_rate_hz: float
    virtual_speed: float
    free_release_rad: float
    impact_release_rad: float
    decay_max_s: float
    decay_stop_below_rad: float
    sweep_frequency_hz: float
    sweep_betas: tuple[float, ...]
    settle_s: float
    dwell_s: float
    simulated_betas: int
    simulated_periods: int
    simulated_record_periods: int
    analyze_forced_step: bool  # the discrepancy analysis of a sweep step (slow)
    # check the impact decay only for what the free decay found (when it found something)
    # instead of for every candidate: a shortcut of the quick demo
    carry_free_decay_finding: bool


FULL = DemoSettings(
    name="full",
    sample_rate_hz=4000.0,
    virtual_speed=5.0,
    free_release_rad=0.15,
    impact_release_rad=-0.3,
    decay_max_s=60.0,
    decay_stop_below_rad=0.005,
    sweep_frequency_hz=10.0,
    sweep_betas=(0.02, 0.035, 0.05, 0.065, 0.08, 0.095, 0.11, 0.125),
    settle_s=6.0,
    dwell_s=8.0,
    simulated_betas=80,
    simulated_periods=500,
    simulated_record_periods=100,
    analyze_forced_step=True,
    carry_free_decay_finding=False,
)

QUICK = DemoSettings(
    name="quick",
    sample_rate_hz=2000.0,
    virtual_speed=5.0,
    free_release_rad=0.15,
    impact_release_rad=-0.2,
    decay_max_s=30.0,
    decay_stop_below_rad=0.01,
    sweep_frequency_hz=10.0,
    sweep_betas=(0.03, 0.07, 0.11),
    settle_s=3.0,
    dwell_s=5.5,
    simulated_betas=12,
    simulated_periods=200,
    simulated_record_periods=40,
    analyze_forced_step=False,
    carry_free_decay_finding=True,
)


@dataclass
class DemoResult:
    """What the demo left behind and found."""

    folder: Path
    report: Path
    hidden: HiddenCause
    parameters: dict[str, dict[str, Any]]  # the explained model's (baseline + found causes)
    baseline: dict[str, dict[str, Any]]  # the baseline model's identification
    causes: dict[str, dict[str, float]]  # causes found, with their fitted values
    truth: dict[str, float]
    findings: dict[str, str]  # record -> cause named by the discrepancy analysis
    regimes: list[dict[str, Any]]
    timings_s: dict[str, float]
    notes: list[str]

    def _cause_keys(self) -> list[str]:
        return [key for values in self.causes.values() for key in values]

    def summary(self) -> str:
        """A few lines for the terminal."""
        lines = [f"impact-rig demo: report in {self.report}"]
        for key in ("L_m", "zeta", "K_N_per_m1.5", "mu0_s_per_m", *self._cause_keys()):
            if key in self.parameters:
                lines.append("  " + _estimate_text(key, self.parameters[key], self.truth.get(key)))
        if self.findings:
            found = ", ".join(f"{rec}: {cause}" for rec, cause in self.findings.items())
            lines.append(f"  discrepancy analysis named: {found}")
        lines.append(f"  hidden in the virtual rig: {self.hidden.describe()}")
        lines.append(
            "  (parameters of the model the analysis arrived at: the baseline model"
            + "".join(f" + {name}" for name in self.causes)
            + ")"
        )
        if self.regimes:
            kinds = ", ".join(
                f"{r['beta']:.3g}{'^' if r['direction'] == 'up' else 'v'} {r['short']}"
                for r in self.regimes
            )
            lines.append(f"  sweep regimes (beta, ^up/v down): {kinds}")
        lines.extend(f"  note: {n}" for n in self.notes)
        lines.append(f"  total {self.timings_s.get('total', math.nan):.0f} s")
        return "\n".join(lines)


def _estimate_text(key: str, estimate: Mapping[str, Any], truth: float | None) -> str:
    ci = estimate.get("ci95")
    text = f"{key} = {estimate['value']:.6g}"
    if ci:
        text += f"  95% CI [{ci[0]:.6g}, {ci[1]:.6g}]"
    if truth is not None:
        text += f"  (virtual rig: {truth:.6g})"
    return text


# -- preparation ------------------------------------------------------------------------------


def prepare_folder(folder: str | Path, *, overwrite: bool = False) -> Path:
    """Create the report folder; refuse a non-empty one unless ``overwrite``."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise DemoError(f"{folder}: exists and is not a folder")
    if folder.is_dir() and any(folder.iterdir()) and not overwrite:
        raise DemoError(
            f"{folder}: folder is not empty; choose another --out or pass --overwrite "
            "(the demo's files in it are then replaced)"
        )
    try:
        for sub in ("", RECORDINGS, FIGURES, ANALYSIS):
            (folder / sub).mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise DemoError(f"{folder}: cannot create the report folder ({error})") from None
    return folder


def demo_config(config: RigConfig, hidden: HiddenCause) -> RigConfig:
    """The rig file run on the virtual rig, with exactly the hidden cause switched on."""
    causes = {} if hidden.name == NONE else {hidden.name: MappingProxyType(dict(hidden.values))}
    virtual = replace(config.virtual, causes=MappingProxyType(causes))
    return replace(config, kind="virtual", virtual=virtual)


def warm_up_physics(config: RigConfig) -> None:
    """Compile (or load from numba's cache) the virtual rig's physics before the devices stream:
    a first compilation takes tens of seconds, and a board that says nothing that long
    would be taken for a dead one."""
    from analysis.model import Drive, Model, RigParameters
    from analysis.simulate import SimulationSettings, simulate

    rig = RigParameters(L_m=config.constants.L_m)
    model = Model(rig=rig, drive=Drive(amplitude_m=1e-3, frequency_hz=10.0), barrier=True)
    settings = SimulationSettings(duration_s=0.5, fs_hz=1000.0)
    simulate(model, -0.1, settings=settings)
    simulate(replace(model, drive=Drive(), barrier=False), 0.1, settings=settings)


# -- the run ----------------------------------------------------------------------------------


def run_demo(
    folder: str | Path,
    *,
    settings: DemoSettings = FULL,
    hidden: HiddenCause | None = None,
    config_path: str | Path | None = None,
    overwrite: bool = False,
    progress: Progress | None = None,
) -> DemoResult:
    """Record, identify, explain and report on the virtual rig; returns what was found."""
    say = progress or (lambda text: None)
    hidden = hidden or hidden_cause(DEFAULT_CAUSE, DEFAULT_CAUSE_VALUES)
    clock = time.monotonic()
    timings: dict[str, float] = {}
    notes: list[str] = []
    folder = prepare_folder(folder, overwrite=overwrite)
    config = demo_config(load_config(config_path), hidden)
    truth = {**_truth(config), **hidden.values}  # a hidden cause sets its own values

    def lap(name: str) -> None:
        timings[name] = round(time.monotonic() - clock - sum(timings.values()), 2)

    say("[1/6] preparing the compiled physics (slow only the first time after install) ...")
    warm_up_physics(config)
    lap("warm_up")
    say(
        f"[2/6] recording on the virtual rig (pty serial DAQ + Modbus TCP amplifier, "
        f"{settings.virtual_speed:g}x real time, {settings.sample_rate_hz:g} Hz)"
    )
    results = _record_everything(config, folder, settings, say)
    lap("recording")
    for result in results.values():
        if result.samples_lost:
            notes.append(f"{result.path.name}: {result.samples_lost} samples lost")

    from rig.demo_analysis import (
        analyse_discrepancies,
        bifurcation_diagrams,
        classify_steps,
        combined_parameters,
        explained_parameters,
        identified_model,
        identify,
        load_records,
    )
    from rig.demo_report import write_figures, write_json, write_report

    say("[3/6] identifying L, zeta (free decay), K, mu0 (impact decay)")
    records = load_records(results, notes)
    identified = identify(records, folder, say)
    baseline = combined_parameters(identified)
    lap("identification")

    say("[4/6] judging the regime of every sweep step")
    regimes, sections = classify_steps(records["sweep_steps"], say)
    write_json(folder / "sweep_regimes.json", {"steps": regimes})
    lap("regimes")

    say("[5/6] discrepancy analysis (it is not told what the virtual rig hides)")
    findings = analyse_discrepancies(records, regimes, baseline, folder, settings, say, notes)
    parameters, causes = explained_parameters(baseline, findings)
    write_json(
        folder / "parameters.json",
        {
            "parameters": parameters,
            "causes": causes,
            "baseline_identification": baseline,
            "virtual_rig": {
                "parameters": truth,
                "hidden_cause": {"cause": hidden.name, "parameters": dict(hidden.values)},
            },
        },
    )
    lap("discrepancy")

    say("[6/6] bifurcation diagram: measured sweep against the model; figures and report")
    rig = records["impact_decay"].rig_parameters()
    model = identified_model(parameters, rig, settings.sweep_frequency_hz, causes)
    diagrams = bifurcation_diagrams(model, settings, regimes, sections, folder, say)
    figures = write_figures(folder, diagrams, settings)
    lap("report")
    timings["total"] = round(time.monotonic() - clock, 2)
    result = DemoResult(
        folder=folder,
        report=folder / REPORT_NAME,
        hidden=hidden,
        parameters=parameters,
        baseline=baseline,
        causes=causes,
        truth=truth,
        findings={name: value["cause"] for name, value in findings.items() if "cause" in value},
        regimes=regimes,
        timings_s=timings,
        notes=notes,
    )
    write_report(result, settings, results, findings, figures, config)
    write_json(folder / "demo.json", _demo_json(result, settings, results))
    return result


def _truth(config: RigConfig) -> dict[str, float]:
    """The virtual rig's true values under the docs/MODEL.md section 7 keys."""
    from analysis.model import RigParameters

    c = config.constants
    rig = RigParameters(m_kg=c.m_kg, l_m=c.l_m, L_m=c.L_m, R_m=c.R_m, g_m_s2=c.g_m_s2)
    return {
        "L_m": rig.L_m,
        "omega_rad_s": rig.omega_rad_s,
        "zeta": rig.zeta,
        "K_N_per_m1.5": rig.K_N_per_m1_5,
        "E_Pa": rig.E_Pa,
        "mu0_s_per_m": rig.mu0_s_per_m,
        "theta_b_rad": config.virtual.theta_b_rad,
    }


def _record_everything(config: RigConfig, folder: Path, settings: DemoSettings, say: Progress):
    """The three recordings; a device or recording failure is a DemoError saying so."""
    from drivers.interfaces import DeviceError, LimitError
    from rig.engine import AcquisitionError, SubscriberOverrunError
    from rig.procedures import ProcedureError
    from rig.recorder import RecordingError

    failures = (
        DeviceError,
        LimitError,
        RecordingError,
        ProcedureError,
        AcquisitionError,
        SubscriberOverrunError,
    )
    try:
        return _record_on_open_rig(config, folder, settings, say)
    except failures as error:
        raise DemoError(
            f"recording on the virtual rig failed: {error} (the drive was ramped to zero; the "
            f"recordings so far are in {folder / RECORDINGS})"
        ) from None


def _record_on_open_rig(config: RigConfig, folder: Path, settings: DemoSettings, say: Progress):
    from rig.devices import open_rig
    from rig.procedures import DecayPlan, SweepPlan, record_decay, run_sweep

    speed = settings.virtual_speed
    wall = 1.0 / speed  # procedure durations are wall-clock seconds
    L = config.constants.L_m
    out = folder / RECORDINGS
    devices = open_rig(config, sample_rate_hz=settings.sample_rate_hz, virtual_speed=speed)
    results = {}
    try:
        decays = (
            (
                "free_decay",
                settings.free_release_rad,
                "free decay (barrier out): hold, release, record until the swing dies down",
            ),
            ("impact_decay", settings.impact_release_rad, "impact decay (barrier in)"),
        )
        for experiment, release_rad, what in decays:
            say(f"  {what}")
            results[experiment] = record_decay(
                devices,
                out / f"{experiment}.h5",
                DecayPlan(
                    experiment,
                    release_angle_rad=release_rad,
                    stop_below_rad=settings.decay_stop_below_rad,
                    max_duration_s=settings.decay_max_s * wall,
                ),
                notes=f"impact-rig demo: {experiment.replace('_', ' ')}",
                overwrite=True,
                progress=indented(say),
            )
        devices.set_barrier(True)
        f = settings.sweep_frequency_hz
        say(
            f"  forced sweep at {f:g} Hz, beta {settings.sweep_betas[0]:g} .. "
            f"{settings.sweep_betas[-1]:g} and back (A = beta L)"
        )
        results["sweep"] = run_sweep(
            devices,
            out / f"sweep_{f:g}Hz.h5",
            SweepPlan(
                parameter="amplitude",
                values=tuple(beta * L for beta in settings.sweep_betas),
                fixed=f,
                settle_s=settings.settle_s * wall,
                dwell_s=settings.dwell_s * wall,
                down=True,
            ),
            notes=f"impact-rig demo: amplitude sweep at {f:g} Hz",
            overwrite=True,
            progress=indented(say),
        )
    finally:
        devices.close()
    for result in results.values():
        say(
            f"  {result.path.name}: {result.samples_written} samples, {result.samples_lost} lost "
            f"({result.stop_reason})"
        )
    return results


def indented(say: Progress) -> Progress:
    """Progress one level deeper (the steps of a stage)."""
    return lambda text: say(f"    {text}")


def _demo_json(result: DemoResult, settings: DemoSettings, recordings: Mapping[str, Any]):
    return {
        "report": result.report.name,
        "settings": asdict(settings),
        "hidden_cause": {"cause": result.hidden.name, "parameters": dict(result.hidden.values)},
        "found": result.findings,
        "parameters": result.parameters,
        "virtual_rig": result.truth,
        "recordings": {
            name: {
                "path": str(Path(RECORDINGS) / r.path.name),
                "samples_written": r.samples_written,
                "samples_lost": r.samples_lost,
                "stop_reason": r.stop_reason,
                "wall_time_s": round(r.duration_s, 2),
            }
            for name, r in recordings.items()
        },
        "timings_s": result.timings_s,
        "notes": result.notes,
    }
