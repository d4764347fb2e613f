"""The Analysis tab's explanation of a sweep recording: ``analyze_sweep`` run on the
analysis thread, with what the tab shows of it (the measured diagram step by step, the
report's JSON and the report's own figures)."""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


@dataclass(frozen=True)
class MeasuredStep:
    """One measured step as the diagram shows it: its regime and settled stroboscopic
    points (the angle at drive phase 0 of each settled period)."""

    step: int
    direction: int
    setting: float  # the swept value, SI
    regime: str
    points_rad: np.ndarray


@dataclass(frozen=True)
class SweepExplanation:
    """What the analysis of a sweep found (its JSON report), the measured diagram, and the
    figures the report draws (PNG bytes by file name)."""

    report: dict[str, Any]
    parameter: str
    steps: tuple[MeasuredStep, ...]
    figures: tuple[tuple[str, bytes], ...]


def is_sweep_recording(path: str | Path) -> bool:
    """Whether ``path`` is a sweep (a recording with ``/sweep_steps``, a sweep's CSV)."""
    from analysis.sweep.load import is_sweep

    return is_sweep([path])


def explain_sweep(path: str | Path,
                  progress: Callable[[str], None] | None = None) -> SweepExplanation:
    """Run ``analyze_sweep`` on the sweep in ``path`` (blocking: call on a worker); a file
    that is no usable sweep raises its loader's one-line error."""
    from analysis.report.sweep import sweep_report_json, write_sweep_report
    from analysis.sweep.analyze import analyze_sweep
    from analysis.sweep.diagram import judge_measured
    from analysis.sweep.load import load_sweep

    sweep = load_sweep([path])
    analysis = analyze_sweep(sweep, threads=1, progress=progress)
    steps = tuple(
        MeasuredStep(step.number, step.direction, sweep.setting(step), judged.short,
                     judged.cloud[:, 0] if judged.cloud.size else np.zeros(0))
        for step, judged in zip(sweep.steps, judge_measured(sweep), strict=True))
    with tempfile.TemporaryDirectory(prefix="impact-rig-sweep-") as folder:
        write_sweep_report(analysis, folder)
        figures = tuple((png.name, png.read_bytes()) for png in sorted(Path(folder).rglob("*.png")))
    return SweepExplanation(sweep_report_json(analysis), sweep.parameter, steps, figures)


def sweep_lines(explanation: SweepExplanation) -> list[str]:
    """The explanation in words: the causes, the residual, and the steps' regimes."""
    sweep = explanation.report["sweep"]
    causes = sweep["causes"]
    named = causes["named"]
    lines = [
        f"sweep of {len(sweep['steps'])} steps over the drive's {sweep['parameter']}: "
        + (f"cause {', '.join(named)}" if named else "no cause needed"),
        f"rms residual: baseline {causes['baseline_rms_residual']:.3g} rad, explained "
        f"{causes['final_rms_residual']:.3g} rad (noise {sweep['noise_rad']:.3g} rad)",
    ]
    diagram = sweep.get("diagram")
    if isinstance(diagram, dict) and diagram.get("summary"):
        lines.append(str(diagram["summary"]))
    lines += [f"caution: {w}" for w in explanation.report.get("warnings", [])]
    lines += [f"step {s['step']} set aside: {s['reason']}" for s in sweep["set_aside"]]
    return lines


def step_table(explanation: SweepExplanation) -> list[str]:
    """The per-step table: setting, direction, the measured regime, residual / noise."""
    unit = "m" if explanation.parameter == "amplitude" else "Hz"
    lines = [f"step  dir   setting [{unit}]  regime measured   rms/noise  explained/noise"]
    regimes = {s.step: s.regime for s in explanation.steps}
    for step in explanation.report["sweep"]["steps"]:
        direction = {1: "up", -1: "down"}.get(step["direction"], "-")
        lines.append(f"{step['step']:>4}  {direction:<4}  {step['setting']:>12.4g}  "
                     f"{regimes.get(step['step'], step['regime']):<16}  "
                     f"{step['rms_over_noise']:>9.3g}  {step['explained_rms_over_noise']:>15.3g}")
    return lines
