"""Write a sweep's analysis as JSON and as a page (Markdown and HTML): it leads with the
bifurcation diagrams (the baseline's and the explained model's over the measured points,
the explained model's periodic orbits under them) and a table of the steps' regimes,
measured and simulated; then the one rig's shared parameters, a table of the steps
(setting, drive measured, regime, residual) and the steps set aside."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from analysis import quantities as q
from analysis.dynamics.continuation import ContinuationResult
from analysis.estimate_text import estimate_text
from analysis.json_output import json_ready, write_json
from analysis.provenance import markdown_provenance, provenance
from analysis.report.pages import write_page
from analysis.sweep.analyze import EXPLAINED_NAME, SweepAnalysis, SweepDiagram, report_json
from analysis.sweep.diagram import model_orbits
from analysis.sweep.figure import draw_diagrams

# The explained model's orbits are drawn when their continuation ends within this time
# and this many points on a branch.
ORBITS_SECONDS = 60.0
ORBIT_POINTS = 150


class _OutOfTimeError(Exception):
    """The continuation ran past its time."""


def explained_orbits(diagrams: SweepDiagram, *, seconds: float = ORBITS_SECONDS
                     ) -> tuple[ContinuationResult | None, str]:
    """The explained model's periodic orbits over the sweep's way up
    (:func:`analysis.sweep.diagram.model_orbits`), given up after ``seconds``; with why
    there are none (empty when there are)."""
    comparison = diagrams.explained or diagrams.baseline
    model = diagrams.models[comparison.name]
    deadline = time.perf_counter() + seconds

    def in_time(message: str) -> None:
        if time.perf_counter() > deadline:
            raise _OutOfTimeError

    try:
        orbits = model_orbits(comparison, model, diagrams.sweep,
                              max_points=ORBIT_POINTS, progress=in_time)
    except _OutOfTimeError:
        return None, f"their continuation took longer than {seconds:g} s"
    if orbits is None:
        return None, ("no periodic orbit to continue from: no step of the way up was "
                      "judged periodic in the simulation, or Newton's method found no orbit "
                      "there")
    return orbits, ""


def sweep_report_json(analysis: SweepAnalysis) -> dict[str, Any]:
    """The sweep's JSON report as written (plain values, non-finite numbers as None)."""
    return json_ready(report_json(analysis))


def _fmt(est: dict[str, Any] | None) -> str:
    if not est:
        return "-"
    ci = est.get("ci95")
    return estimate_text(est["value"], tuple(ci) if ci else None)


def write_sweep_report(
    analysis: SweepAnalysis, directory: str | Path, name: str = "sweep", *,
    overwrite: bool = False,
) -> Path:
    """Write NAME.md, NAME.html and NAME.json into ``directory``; returns the .md path (an
    existing NAME.json is refused unless ``overwrite``)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    js = sweep_report_json(analysis)
    write_json(directory / f"{name}.json", {**js, "provenance": provenance()},
               overwrite=overwrite)
    sweep = js["sweep"]
    unit = "m" if sweep["parameter"] == "amplitude" else "Hz"
    lines = [f"# Sweep analysis: {Path(sweep['source']).name or 'sweep'}", ""]
    if analysis.diagrams is not None:
        lines += _diagram_section(analysis.diagrams, sweep["diagram"], directory, name)
        lines += ["## One rig for every step", ""]
    lines += [
        f"- {len(sweep['steps'])} steps over the drive's {sweep['parameter']}, one rig "
        f"fitted to all of them (model: {', '.join(sweep['model']) or 'baseline'})",
        f"- rms residual {sweep['rms_residual']:.3g} rad over every step (noise "
        f"{sweep['noise_rad']:.3g} rad)",
    ]
    causes = sweep["causes"]
    lines.append(f"- **cause: `{sweep['cause']}`**" if len(causes["named"]) <= 1 else
                 "- **causes: " + ", ".join(f"`{c}`" for c in causes["named"]) + "**")
    for entry in causes["selected"]:
        params = ", ".join(f"{k} = {_fmt(v)}" for k, v in entry["parameters"].items())
        state = "shared by every step" if entry["named"] else "not named: its size differs " \
            "from step to step"
        lines.append(f"  - `{entry['cause']}`: {params} ({state}); {entry['why']}")
    lines.append(f"- baseline rms residual {causes['baseline_rms_residual']:.3g} rad, "
                 f"explained {causes['final_rms_residual']:.3g} rad")
    lines += [f"- **caution:** {w}" for w in js["warnings"]]
    lines += [f"- residual finding ({f['kind']}): {f['text']}"
              for f in sweep["residual_findings"]]
    lines += ["", "## Shared parameters", "", "| parameter | value [95 % interval] |",
              "|---|---|"]
    lines += [f"| {k} | {_fmt(v)} |" for k, v in sweep["shared"].items()]
    lines += ["", "## Steps", "",
              f"| step | direction | setting [{unit}] | drive measured | regime | "
              "residual / noise (rig) | explained / noise |", "|---|---|---|---|---|---|---|"]
    for step in sweep["steps"]:
        drive = step["drive"]
        measured = f"{drive[q.frequency_hz]:.6g} Hz"
        if drive.get("table"):
            measured += f", {_fmt(drive['table'][q.amplitude_m])} m"
        direction = {1: "up", -1: "down"}.get(step["direction"], "-")
        lines.append(f"| {step['step']} | {direction} | {step['setting']:.4g} | {measured} | "
                     f"{step['regime']} | {step['rms_over_noise']:.3g} | "
                     f"{step['explained_rms_over_noise']:.3g} |")
    if sweep["set_aside"]:
        lines += ["", "Steps set aside:", ""]
        lines += [f"- step {s['step']}: {s['reason']}" for s in sweep["set_aside"]]
    lines += ["", f"Rules: {analysis.policy.summary()}."]
    lines += markdown_provenance()
    return write_page(lines, directory / f"{name}.md")


def _diagram_section(diagrams: SweepDiagram, js: dict[str, Any], directory: Path,
                     name: str) -> list[str]:
    """The diagrams over the measured points and the per-step table of regimes."""
    title = Path(diagrams.sweep.source).name
    lines = ["## Bifurcation diagram", "", f"**{js['summary']}**", ""]
    base_png = draw_diagrams([diagrams.baseline], diagrams.measured,
                             directory / f"{name}_diagram_baseline.png",
                             title=f"{title}: baseline")
    lines += [f"![baseline over the measured diagram]({base_png.name})", ""]
    orbits, why = explained_orbits(diagrams)
    explained = diagrams.explained or diagrams.baseline
    label = EXPLAINED_NAME if diagrams.explained is not None else "baseline"
    if diagrams.explained is not None:
        png = draw_diagrams([diagrams.explained], diagrams.measured,
                            directory / f"{name}_diagram_explained.png",
                            title=f"{title}: {EXPLAINED_NAME} "
                            f"({', '.join(diagrams.named)})",
                            orbits=orbits, orbits_of=label)
        lines += [f"![explained model over the measured diagram]({png.name})", ""]
    else:
        lines += ["No cause is named: the explained model is the baseline.", ""]
        if orbits is not None:
            png = draw_diagrams([diagrams.baseline], diagrams.measured,
                                directory / f"{name}_diagram_orbits.png",
                                title=f"{title}: baseline and its orbits",
                                orbits=orbits, orbits_of=label)
            lines += [f"![the baseline's periodic orbits]({png.name})", ""]
    lines.append(f"The {label}'s periodic orbits (stable solid, unstable dashed) are drawn "
                 "under its points." if orbits is not None else
                 f"The {label}'s periodic orbits are not drawn: {why}.")
    setting = q.beta if diagrams.baseline.parameter == "amplitude" else "f [Hz]"
    lines += ["", "| step | direction | " + setting + " | measured | baseline | "
              "distance / noise | explained | distance / noise |",
              "|---|---|---|---|---|---|---|---|"]
    for k, base in enumerate(diagrams.baseline.steps):
        ex = explained.steps[k]
        direction = {1: "up", -1: "down"}.get(base.direction, "-")
        lines.append(
            f"| {base.number} | {direction} | {base.setting:.4g} | {base.measured} | "
            f"{_regime(base.simulated, base.agrees)} | {_distance(base.distance)} | "
            f"{_regime(ex.simulated, ex.agrees)} | {_distance(ex.distance)} |")
    lines += ["", "A regime in bold agrees with the measured one; the distance is between "
              "the settled stroboscopic clouds, in units of the measured points' noise "
              "(about 1: one orbit seen through the noise).", ""]
    return lines


def _regime(regime: str, agrees: bool) -> str:
    return f"**{regime}**" if agrees else regime


def _distance(value: float) -> str:
    return "-" if value != value else f"{value:.3g}"
