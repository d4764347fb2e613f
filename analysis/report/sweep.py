"""Write a sweep's analysis as JSON and as a page (Markdown and HTML): the one rig's
shared parameters, then a table of the steps (setting, drive measured, regime, residual)
and the steps set aside."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from analysis.estimate_text import estimate_text
from analysis.json_output import json_ready, write_json
from analysis.provenance import markdown_provenance, provenance
from analysis.report.pages import write_page
from analysis.sweep.analyze import SweepAnalysis, report_json


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
    lines = [
        f"# Sweep analysis: {Path(sweep['source']).name or 'sweep'}",
        "",
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
        measured = f"{drive['frequency_hz']:.6g} Hz"
        if drive.get("table"):
            measured += f", {_fmt(drive['table']['amplitude_m'])} m"
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
