"""The Analysis tab's explanation of a sweep recording: ``analyze_sweep`` run on the
analysis thread, with what the tab shows of it (the measured diagram step by step, the
report's JSON and the report's own figures)."""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.progress import ProgressText

if TYPE_CHECKING:
    from analysis.sweep.diagram import JudgedStep


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
    """What the analysis of a sweep found (its JSON report), the measured diagram, each
    model's diagram as simulated through the sweep (name, its steps; none when the analysis
    did not compare them), and the figures the report draws (PNG bytes by file name)."""

    report: dict[str, Any]
    parameter: str
    steps: tuple[MeasuredStep, ...]
    figures: tuple[tuple[str, bytes], ...]
    models: tuple[tuple[str, tuple[MeasuredStep, ...]], ...] = ()


def is_sweep_recording(path: str | Path) -> bool:
    """Whether ``path`` is a sweep (a recording with ``/sweep_steps``, a sweep's CSV)."""
    from analysis.record_loaders import is_sweep

    return is_sweep([path])


def explain_sweep(path: str | Path,
                  progress: ProgressText | None = None) -> SweepExplanation:
    """Run ``analyze_sweep`` on the sweep in ``path`` (blocking: call on a worker); a file
    that is no usable sweep raises its loader's one-line error."""
    from analysis.report.sweep import sweep_report_json, write_sweep_report
    from analysis.sweep.analyze import analyze_sweep
    from analysis.sweep.diagram import judge_measured
    from analysis.sweep.load import load_sweep

    sweep = load_sweep([path])
    analysis = analyze_sweep(sweep, threads=1, progress=progress)
    diagrams = analysis.diagrams
    measured = judge_measured(sweep) if diagrams is None else diagrams.measured
    setting = {step.number: (step.direction, sweep.setting(step)) for step in sweep.steps}

    def shown(judged: Sequence[JudgedStep]) -> tuple[MeasuredStep, ...]:
        return tuple(MeasuredStep(j.number, *setting[j.number], j.short,
                                  j.cloud[:, 0] if j.cloud.size else np.zeros(0))
                     for j in judged)

    models = () if diagrams is None else tuple(
        (comparison.name, shown(comparison.judged)) for comparison in diagrams.comparisons)
    with tempfile.TemporaryDirectory(prefix="impact-rig-sweep-") as folder:
        write_sweep_report(analysis, folder)
        figures = tuple((png.name, png.read_bytes()) for png in sorted(Path(folder).rglob("*.png")))
    return SweepExplanation(sweep_report_json(analysis), sweep.parameter, shown(measured),
                            figures, models)


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
    """The per-step table: setting, direction, the regime measured and each model's,
    residual / noise."""
    unit = "m" if explanation.parameter == "amplitude" else "Hz"
    regimes = [{s.step: s.regime for s in explanation.steps}]
    regimes += [{s.step: s.regime for s in steps} for _, steps in explanation.models]
    names = ["measured", *(name for name, _ in explanation.models)]
    lines = [f"step  dir   setting [{unit}]  " + "".join(f"{n[:16]:<17}" for n in names)
             + " rms/noise  explained/noise"]
    for step in explanation.report["sweep"]["steps"]:
        direction = {1: "up", -1: "down"}.get(step["direction"], "-")
        lines.append(f"{step['step']:>4}  {direction:<4}  {step['setting']:>12.4g}  "
                     + "".join(f"{r.get(step['step'], '-'):<17}" for r in regimes)
                     + f" {step['rms_over_noise']:>9.3g}  "
                     f"{step['explained_rms_over_noise']:>15.3g}")
    return lines
