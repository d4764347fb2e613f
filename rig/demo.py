"""The end-to-end demonstration: the virtual rig with a hidden physical effect, recorded and
explained by the same drivers, procedures and analysis a real rig uses, into a report folder.

The virtual rig runs over its real protocols (serial DAQ on a pty, amplifier on
Modbus TCP), faster than real time, with one named cause of MODEL.md section 6
switched on that the baseline model lacks.  The demo records a free decay, an
impact decay and a forced amplitude sweep at 10 Hz (up and down); identifies L,
zeta, K and mu0 with intervals; runs the discrepancy analysis on every record
(without being told the cause); classifies the regime of every sweep step; and
draws the measured bifurcation diagram against the one simulated with the
identified model.  Only at the end is the hidden cause revealed, next to what
the analysis named.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

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
    from analysis.simulate import simulate

    rig = RigParameters(L_m=config.constants.L_m)
    model = Model(rig=rig, drive=Drive(amplitude_m=1e-3, frequency_hz=10.0), barrier=True)
    simulate(model, -0.1, duration_s=0.5, fs_hz=1000.0)
    simulate(replace(model, drive=Drive(), barrier=False), 0.1, duration_s=0.5, fs_hz=1000.0)


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
    truth = _truth(config)

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

    say("[3/6] identifying L, zeta (free decay), K, mu0 (impact decay)")
    records = _load_records(results, notes)
    identified = _identify(records, folder, say)
    baseline = _combined_parameters(identified)
    lap("identification")

    say("[4/6] classifying the regime of every sweep step")
    regimes, sections = _classify_steps(records["sweep_steps"], say)
    _write_json(folder / "sweep_regimes.json", {"steps": regimes})
    lap("regimes")

    say("[5/6] discrepancy analysis (it is not told what the virtual rig hides)")
    findings = _discrepancy(records, regimes, folder, settings, say, notes)
    parameters, causes = explained_parameters(baseline, findings)
    _write_json(
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
    from rig.demo_report import write_figures, write_report

    rig = records["impact_decay"].rig_parameters()
    model = identified_model(parameters, rig, settings.sweep_frequency_hz, causes)
    diagrams = _bifurcation(model, settings, regimes, sections, folder, say)
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
    _write_json(folder / "demo.json", _demo_json(result, settings, results))
    return result


def _truth(config: RigConfig) -> dict[str, float]:
    """The virtual rig's true values under the MODEL.md section 7 keys."""
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
    from rig.devices import open_rig
    from rig.procedures import DecayPlan, SweepPlan, record_decay, run_sweep

    speed = settings.virtual_speed
    wall = 1.0 / speed  # procedure durations are wall-clock seconds
    L = config.constants.L_m
    out = folder / RECORDINGS
    devices = open_rig(config, sample_rate_hz=settings.sample_rate_hz, virtual_speed=speed)
    results = {}
    try:
        say("  free decay (barrier out): hold, release, record until the swing dies down")
        results["free_decay"] = record_decay(
            devices,
            out / "free_decay.h5",
            DecayPlan(
                "free_decay",
                release_angle_rad=settings.free_release_rad,
                stop_below_rad=settings.decay_stop_below_rad,
                max_duration_s=settings.decay_max_s * wall,
            ),
            notes="impact-rig demo: free decay",
            overwrite=True,
            progress=_indented(say),
        )
        say("  impact decay (barrier in)")
        results["impact_decay"] = record_decay(
            devices,
            out / "impact_decay.h5",
            DecayPlan(
                "impact_decay",
                release_angle_rad=settings.impact_release_rad,
                stop_below_rad=settings.decay_stop_below_rad,
                max_duration_s=settings.decay_max_s * wall,
            ),
            notes="impact-rig demo: impact decay",
            overwrite=True,
            progress=_indented(say),
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
            progress=_indented(say),
        )
    finally:
        devices.close()
    for result in results.values():
        say(
            f"  {result.path.name}: {result.samples_written} samples, {result.samples_lost} lost "
            f"({result.stop_reason})"
        )
    return results


def _indented(say: Progress) -> Progress:
    return lambda text: say(f"    {text}")


def _load_records(results: Mapping[str, Any], notes: list[str]) -> dict[str, Any]:
    """Decays as their longest gap-free stretch, the sweep one record per step."""
    from analysis.hdf5_records import load_hdf5_segments, load_hdf5_steps
    from analysis.records import RecordFormatError

    records: dict[str, Any] = {}
    for name in ("free_decay", "impact_decay"):
        segments = load_hdf5_segments(results[name].path)
        if len(segments) > 1:
            notes.append(
                f"{results[name].path.name}: {len(segments) - 1} gap(s); the longest gap-free "
                "stretch is analysed"
            )
        records[name] = max(segments, key=lambda r: r.time_s.size)
    try:
        records["sweep_steps"] = load_hdf5_steps(results["sweep"].path)
    except RecordFormatError as error:  # samples lost in a step's dwell: no regimes then
        notes.append(f"the sweep's steps cannot be analysed: {error}")
        records["sweep_steps"] = []
    return records


def _identify(records: Mapping[str, Any], folder: Path, say: Progress) -> dict[str, Any]:
    from analysis.identify import IdentificationError, fit_free_decay, fit_impact_decay

    try:
        free = fit_free_decay(records["free_decay"])
        say("  free decay: " + free.summary().splitlines()[1].strip())
        hold = {"L_m": free["L_m"].value, "zeta": free["zeta"].value}
        impact = fit_impact_decay(records["impact_decay"], hold=hold)
    except IdentificationError as error:
        raise DemoError(f"identification failed: {error}") from None
    for name, result in (("free_decay", free), ("impact_decay", impact)):
        report = result.as_json()
        report["source"] = str(records[name].source)
        _write_json(folder / f"identify_{name}.json", report)
    say(
        f"  impact decay: K = {impact['K_N_per_m1.5'].value:.4g} N/m^1.5, "
        f"mu0 = {impact['mu0_s_per_m'].value:.3g} s/m"
    )
    return {"free_decay": free, "impact_decay": impact}


def _combined_parameters(identified: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """L, omega, zeta from the free decay; K, E, R, mu0, theta_b from the impact decay."""
    out: dict[str, dict[str, Any]] = {}
    free, impact = identified["free_decay"], identified["impact_decay"]
    for key in ("L_m", "omega_rad_s", "zeta"):
        out[key] = free[key].as_json() | {"from": "free_decay"}
    for key in ("K_N_per_m1.5", "E_Pa", "R_m", "mu0_s_per_m", "theta_b_rad"):
        if key in impact.parameters:
            out[key] = impact[key].as_json() | {"from": "impact_decay"}
    return out


def _classify_steps(steps: list[Any], say: Progress) -> tuple[list[dict[str, Any]], list[Any]]:
    """Regime of each step from its tachometer Poincare section (one point per drive period)."""
    from analysis.dynamics import poincare_from_pulses

    regimes, sections = [], []
    previous_beta = -math.inf
    for number, record in enumerate(steps):
        drive = record.drive
        beta = drive["amplitude_m"] / record.rig_parameters().L_m
        direction = "up" if beta >= previous_beta else "down"
        previous_beta = beta
        entry: dict[str, Any] = {
            "step": number,
            "direction": direction,
            "beta": beta,
            "amplitude_m": drive["amplitude_m"],
            "frequency_hz": drive["frequency_hz"],
            "duration_s": float(record.time_s[-1] - record.time_s[0]),
            "poincare_points": int(record.tach_indices.size),
        }
        section = None
        try:
            section = poincare_from_pulses(record.angle_rad, record.sample_rate_hz,
                                           record.tach_indices)
            regime = _regime(record, section)
            entry.update(kind=regime.kind, period=regime.period, label=regime.label)
            entry["short"] = regime.short_name
        except ValueError as error:
            entry.update(kind="unclassified", period=None, label=f"unclassified: {error}")
            entry["short"] = "unclassified"
        sections.append(section.theta[-SETTLED_POINTS:] if section is not None else np.zeros(0))
        say(f"  step {number} ({direction}) beta {beta:.3g}: {entry['label']}")
        regimes.append(entry)
    return regimes, sections


# A measured Poincare point never returns exactly: sensor noise, the noise of the smoothed
# rate and what is left of the transient keep it within a few percent of the attractor.
MEASURED_RECURRENCE_TOLERANCE = 0.03
SETTLED_POINTS = 30  # the last points of a step: the settled response


def _regime(record, section):
    """Periodic when the settled points (the last ones) recur; otherwise the 0-1 test on all."""
    from analysis.dynamics import classify_motion

    fs, f = record.sample_rate_hz, record.drive["frequency_hz"]
    noise, _ = _noise(record.angle_rad)
    tolerance = max(MEASURED_RECURRENCE_TOLERANCE, 10.0 * noise / (np.ptp(record.angle_rad) or 1.0))
    tail = section.tail(min(len(section), max(SETTLED_POINTS, len(section) // 2)))
    with contextlib.suppress(ValueError):  # too few settled points to call it non-periodic
        settled = classify_motion(record.angle_rad, fs, f, tail, tolerance=tolerance)
        if settled.kind == "periodic":
            return settled
    return classify_motion(record.angle_rad, fs, f, section, tolerance=tolerance)


def _noise(angle: np.ndarray) -> tuple[float, float]:
    from analysis.identify.preprocess import noise_and_quantum

    return noise_and_quantum(np.asarray(angle, dtype=float))


def _discrepancy(
    records: Mapping[str, Any],
    regimes: list[dict[str, Any]],
    folder: Path,
    settings: DemoSettings,
    say: Progress,
    notes: list[str],
) -> dict[str, dict[str, Any]]:
    """The discrepancy analysis (analysis.discrepancy) on each decay and on one sweep step."""
    try:
        from analysis.discrepancy import AnalysisError, analyze_record
        from analysis.report import write_report as write_analysis_report
    except ImportError as error:
        notes.append(f"the discrepancy analysis is not available in this installation ({error})")
        say(f"  skipped: {notes[-1]}")
        return {}
    chosen = {
        "free_decay": records["free_decay"],
        "impact_decay": records["impact_decay"],
    }
    steps = records["sweep_steps"]
    if steps and settings.analyze_forced_step:
        chosen["forced_step"] = _forced_step_to_analyse(steps, regimes)
    findings: dict[str, dict[str, Any]] = {}
    for name, record in chosen.items():
        causes = None
        found = findings.get("free_decay", {}).get("cause", NONE)
        if name == "impact_decay" and settings.carry_free_decay_finding and found != NONE:
            causes = [found]
            notes.append(
                f"quick demo: the impact decay was checked for {found} only (what the free "
                "decay showed); the full demo tries every candidate cause"
            )
        say(f"  {name}:" + (f" (candidates: {', '.join(causes)})" if causes else ""))
        try:
            analysis = analyze_record(record, progress=_indented(say), causes=causes)
        except (AnalysisError, ValueError) as error:
            notes.append(f"discrepancy analysis of {name} failed: {error}")
            say(f"    failed: {error}")
            continue
        page = write_analysis_report(analysis, folder / ANALYSIS, name=name)
        findings[name] = {**analysis.as_json(), "page": str(page.relative_to(folder))}
    return findings


def _forced_step_to_analyse(steps: list[Any], regimes: list[dict[str, Any]]):
    """A settled periodic step (a forced record is fitted point by point): the lowest period,
    then the smallest drive, preferring the way down (longer settled); else the first step."""
    periodic = [
        (r["period"], r["direction"] != "down", r["beta"], r["step"])
        for r in regimes
        if r["kind"] == "periodic"
    ]
    return steps[min(periodic)[-1]] if periodic else steps[0]


def _bifurcation(
    model,
    settings: DemoSettings,
    regimes: list[dict[str, Any]],
    sections: list[np.ndarray],
    folder: Path,
    say: Progress,
):
    """Simulated (the identified model, continuation up and down) and measured diagrams."""
    from analysis.dynamics import bifurcation_from_recording, simulate_bifurcation

    betas = np.linspace(
        min(settings.sweep_betas) * 0.5, max(settings.sweep_betas) * 1.04, settings.simulated_betas
    )
    say(
        f"  simulating {betas.size} beta values x {settings.simulated_periods} periods, "
        "up and down"
    )
    simulated = simulate_bifurcation(
        model,
        betas,
        periods=settings.simulated_periods,
        record_periods=settings.simulated_record_periods,
        mode="continuation",
    )
    diagrams = simulated
    if regimes:
        measured = bifurcation_from_recording([r["beta"] for r in regimes], sections)
        diagrams = (*simulated, measured)
    _write_json(
        folder / "bifurcation.json",
        {
            "frequency_hz": settings.sweep_frequency_hz,
            "model": {
                "rig": model.rig.as_dict(),
                "extensions": {k: dict(v) for k, v in model.extensions.items()},
            },
            "diagrams": [
                {
                    "direction": d.direction,
                    "parameter": d.parameter_name,
                    "values": d.parameter.tolist(),
                    "theta_rad": [[v for v in row if math.isfinite(v)] for row in d.theta.tolist()],
                }
                for d in diagrams
            ],
        },
    )
    return diagrams


def identified_model(
    parameters: Mapping[str, Mapping[str, Any]],
    rig,
    frequency_hz: float,
    causes: Mapping[str, Mapping[str, float]] | None = None,
):
    """The model with identified L, zeta, K, mu0 (and theta_b) on the recording's rig constants
    (m, l, R, g: ``rig``), the found causes switched on, driven at ``frequency_hz``."""
    from analysis.model import Drive, Model

    values = {
        key: parameters[key]["value"]
        for key in ("L_m", "zeta", "mu0_s_per_m", "theta_b_rad")
        if key in parameters
    }
    fitted = rig.with_values(**values).with_stiffness(parameters["K_N_per_m1.5"]["value"])
    model = Model(rig=fitted, drive=Drive(amplitude_m=0.0, frequency_hz=frequency_hz))
    for name, cause_values in (causes or {}).items():
        model = model.with_extension(name, **cause_values)
    return model


def explained_parameters(
    baseline: Mapping[str, Mapping[str, Any]], findings: Mapping[str, Mapping[str, Any]]
) -> tuple[dict[str, dict[str, Any]], dict[str, dict[str, float]]]:
    """Parameters of the model the discrepancy analysis arrived at, and the causes it added.

    L, omega, zeta come from the free decay's extended fit, K, E, mu0, theta_b from the
    impact decay's (each record's own finding); without a finding, the baseline's values.
    Each cause takes its parameters from the record that found it (the impact decay first).
    A forced record's finding is reported but not merged: its fit starts from the decays'
    values and judges a short steady state, so it refines what they found rather than
    founding the model.
    """
    from analysis.extensions import NONE as NO_CAUSE
    from analysis.extensions import cause

    out = {key: dict(value) for key, value in baseline.items()}
    sources = {
        "free_decay": ("L_m", "omega_rad_s", "zeta"),
        "impact_decay": ("K_N_per_m1.5", "E_Pa", "mu0_s_per_m", "theta_b_rad"),
    }
    causes: dict[str, dict[str, float]] = {}
    for name in ("impact_decay", "free_decay"):
        report = findings.get(name)
        if not report:
            continue
        extended = report.get("extended", {}).get("parameters", {})
        for key in sources.get(name, ()):
            if key in extended and "value" in extended[key]:
                out[key] = {**extended[key], "from": f"{name}, extended model"}
        found = report.get("cause", NO_CAUSE)
        if found != NO_CAUSE and found not in causes:
            names = [spec.name for spec in cause(found).parameters]
            causes[found] = {k: extended[k]["value"] for k in names if k in extended}
            for k in names:
                if k in extended:
                    out[k] = {**extended[k], "from": f"{name}, extended model"}
    return out, causes


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


def _write_json(path: Path, data: Any) -> None:
    path.write_text(json.dumps(_plain(data), indent=1, allow_nan=True) + "\n", encoding="utf-8")


def _plain(value: Any) -> Any:
    """JSON-ready copy: numpy scalars and arrays, tuples and mappings made plain."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value
