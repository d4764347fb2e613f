"""What the demo tells: its result and the terminal summary, the report folder's figures
(matplotlib, Agg), the report page (Markdown and HTML) that ties the recordings, the
identified parameters, the discrepancy findings and the regimes together, and the JSON files.

The report is the demo's edge: the stages hand it the analysis's own results, and only
here are they written out (every JSON file through analysis.json_output)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from analysis import quantities as q
from analysis.estimate_text import estimate_text, interval_determined, interval_text
from analysis.figure_style import save_figure
from analysis.json_output import write_json
from analysis.provenance import markdown_provenance, provenance
from analysis.report.pages import write_page
from rig.demo.settings import ANALYSIS, FIGURES, RECORDINGS, DemoSettings, HiddenCause

if TYPE_CHECKING:  # the analysis's result types, for the hints only (imported when run)
    from analysis.discrepancy import Analysis
    from analysis.dynamics import BifurcationDiagram
    from analysis.identify import IdentificationResult
    from analysis.model import Model
    from analysis.sweep.analyze import SweepAnalysis


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
    # the sweep explained as one (write_sweep_explanation); None when it could not be
    sweep: dict[str, Any] | None = None

    def _cause_keys(self) -> list[str]:
        return [key for values in self.causes.values() for key in values]

    def summary(self) -> str:
        """A few lines for the terminal."""
        lines = [f"impact-rig demo: report in {self.report} (for a browser: "
                 f"{self.report.with_suffix('.html').name})"]
        for key in (q.L_m, q.zeta, q.K_N_per_m1_5, q.mu0_s_per_m, *self._cause_keys()):
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
                f"{r[q.beta]:.3g}{'^' if r['direction'] == 'up' else 'v'} {r['short']}"
                for r in self.regimes
            )
            lines.append(f"  sweep regimes (beta, ^up/v down): {kinds}")
        lines.extend(f"  {line}" for line in sweep_lines(self.sweep))
        lines.extend(f"  note: {n}" for n in self.notes)
        lines.append(f"  total {self.timings_s.get('total', math.nan):.0f} s")
        return "\n".join(lines)


def _estimate_text(key: str, estimate: Mapping[str, Any], truth: float | None) -> str:
    text = f"{key} = {estimate_text(estimate['value'], estimate.get('ci95'))}"
    if truth is not None:
        text += f"  (virtual rig: {truth:.6g})"
    return text


def write_sweep_explanation(folder: Path, analysis: SweepAnalysis, *,
                            overwrite: bool) -> dict[str, Any]:
    """The sweep explained as one: its report (Markdown, HTML, JSON and figures) in the
    folder's analysis/, and what the demo's summary and report say of it: the causes named,
    each model's diagram against the measured one, the page and its figures (relative to
    the folder)."""
    from analysis.report.sweep import sweep_report_json, write_sweep_report
    before = set((folder / ANALYSIS).rglob("*.png"))
    page = write_sweep_report(analysis, folder / ANALYSIS, "sweep", overwrite=overwrite)
    figures = sorted(set((folder / ANALYSIS).rglob("*.png")) - before)
    sweep = sweep_report_json(analysis)["sweep"]
    return {
        "page": str(page.relative_to(folder)),
        "figures": [str(f.relative_to(folder)) for f in figures],
        "steps": len(sweep["steps"]),
        "set_aside": len(sweep["set_aside"]),
        "causes": list(sweep["causes"]["named"]),
        "diagram": diagram_agreement(sweep["diagram"]),
    }


def diagram_agreement(diagram: Any) -> list[dict[str, Any]]:
    """Each model's comparison of its diagram with the measured one, as the sweep's
    analysis gives them (``sweep.diagram`` of its report, docs/MODEL.md): model name,
    agreeing steps, steps judged, summary; [] when no comparison ran."""
    found: list[dict[str, Any]] = []

    def visit(node: Any) -> None:
        if isinstance(node, dict):
            if "agreeing_steps" in node and "steps" in node:
                judged = [s for s in node["steps"] if s.get("measured") != "undetermined"]
                found.append({"model": node.get("model", "?"),
                              "agreeing": int(node["agreeing_steps"]), "judged": len(judged),
                              "steps": len(node["steps"]),
                              "summary": node.get("summary", "")})
                return
            for value in node.values():
                visit(value)
        elif isinstance(node, list):
            for value in node:
                visit(value)

    visit(diagram)
    return found

def sweep_lines(sweep: Mapping[str, Any] | None) -> list[str]:
    """What the sweep explained as one found, in a few lines: the causes that hold across
    its steps, and whether the explained model's diagram agrees with the measured one."""
    if sweep is None:
        return []
    causes = ", ".join(sweep["causes"]) or "none"
    lines = [f"sweep explained as one rig over {sweep['steps']} steps: cause(s) {causes}"]
    models = sweep["diagram"]
    if not models:
        return [*lines, "  its diagram was not compared with the measured one (the sweep's "
                "analysis gave no diagram comparison)"]
    for model in models:
        lines.append(f"  {model['model']}: {model['agreeing']} of {model['judged']} judged "
                     f"steps agree with the measured regime")
    explained = models[-1]
    verdict = ("agrees with" if explained["agreeing"] == explained["judged"]
               else "does not agree with")
    lines.append(f"  the explained model's diagram {verdict} the measured one")
    return lines


def write_figures(folder: Path, diagrams, settings) -> dict[str, str]:
    """Draw the report's own figure (the bifurcation diagram); name -> path in ``folder``.
    The fits of the records are drawn by the discrepancy analysis's pages."""
    from analysis.dynamics import plot_bifurcation

    path = Path(FIGURES) / "bifurcation.png"
    figure = plot_bifurcation(
        *diagrams,
        title=f"{settings.sweep_frequency_hz:g} Hz amplitude sweep: measured (virtual rig) "
        "vs the identified model",
    )
    for collection, diagram in zip(figure.axes[0].collections, diagrams, strict=False):
        # few simulated points at the demo's resolution: make them show, the measured more so
        collection.set_sizes([30.0 if diagram.direction == "recorded" else 4.0])
    save_figure(figure, folder / path)
    return {"bifurcation": str(path)}


# -- the report page -------------------------------------------------------------------------


def write_report(result, settings, recordings, analyses, pages, figures, config) -> Path:
    """report.md and report.html in the folder: what was done, found, and how it compares
    with the truth (``analyses`` the discrepancy analyses, ``pages`` their pages, by record)."""
    from analysis.report.discrepancy import report_json

    lines: list[str] = []
    add = lines.append
    add("# impact-rig demo report")
    add("")
    add(
        f"Virtual rig '{config.name}' (serial DAQ board on a pseudo-terminal, amplifier on "
        f"Modbus TCP), run {settings.virtual_speed:g}x faster than real time at "
        f"{settings.sample_rate_hz:g} Hz ({settings.name} demo, "
        f"{result.timings_s.get('total', math.nan):.0f} s). The rig simulates the pendulum with "
        "one physical effect that the baseline model of docs/MODEL.md lacks; the analysis below is "
        "not told which one. It is revealed at the end."
    )
    add("")
    add("## Recordings")
    add("")
    add("| experiment | file | samples | lost | stopped |")
    add("|---|---|---|---|---|")
    for name, r in recordings.items():
        add(
            f"| {name} | `recordings/{r.path.name}` | {r.samples_written} | {r.samples_lost} | "
            f"{r.stop_reason} |"
        )
    add("")
    add(
        "Open them with `impact-rig replay`, export them with `impact-rig export FILE --out "
        "FILE.csv`, or analyse them again with `impact-rig identify FILE`."
    )
    add("")
    add("## Identified parameters (95 % intervals)")
    add("")
    model_name = "baseline" + "".join(f" + {name}" for name in result.causes)
    add(
        "First the baseline model of docs/MODEL.md alone (L, zeta from the free decay; K, mu0 from "
        "the impact decay with L and zeta held), then the model the discrepancy analysis "
        f"arrived at (**{model_name}**), against the virtual rig's true values."
    )
    add("")
    add("| parameter | baseline model | 95 % CI | explained model | 95 % CI | true value |")
    add("|---|---|---|---|---|---|")
    for key, estimate in result.parameters.items():
        base = result.baseline.get(key)
        truth = result.truth.get(key)
        truth_text = f"{truth:.6g}" if truth is not None else "-"
        add(
            f"| `{key}` | {_value(base)} | {_interval(base, truth)} | {_value(estimate)} | "
            f"{_interval(estimate, truth)} | {truth_text} |"
        )
    add("")
    add(
        "An interval marked *misses* does not contain the true value: the model is missing "
        "something, and the fit bends its other parameters to make up for it."
    )
    add("")
    add("## Discrepancy analysis")
    add("")
    if not analyses:
        add("The discrepancy analysis did not run (see the notes below).")
    for name, analysis in analyses.items():
        report = report_json(analysis)
        add(f"### {name.replace('_', ' ')}")
        add("")
        add(f"- most probable cause: **{report.get('cause')}**")
        gain = report.get("gain", {})
        if gain:
            add(
                f"- gain of the extended model: rms reduced by "
                f"{100 * gain.get('rms_reduction', 0.0):.1f} %, held-out rms "
                f"{_num(gain.get('heldout_rms_baseline'))} -> "
                f"{_num(gain.get('heldout_rms_extended'))} rad, information criterion "
                f"delta {_num(gain.get('information_criterion_delta'))}"
            )
        add(f"- where the baseline fails: {report.get('localization', '-')}")
        ranking = report.get("ranking", [])[:4]
        if ranking:
            add("- ranking: " + "; ".join(
                f"{entry['cause']} (score {_num(entry.get('score'))})" for entry in ranking
            ))
        page = pages[name]
        add(f"- full analysis: [{page.with_suffix('')}]({page}) "
            f"(and `{page.with_suffix('.json')}`)")
        add("")
        add(f"![{name}: baseline and extended model]({page.with_name(page.stem + '_fit.png')})")
        add("")
    add("## Forced sweep: regimes and bifurcation diagram")
    add("")
    add("| step | direction | beta | Poincare points | regime |")
    add("|---|---|---|---|---|")
    for r in result.regimes:
        add(
            f"| {r['step']} | {r['direction']} | {r[q.beta]:.4g} | {r['poincare_points']} | "
            f"{r['label']} |"
        )
    add("")
    if "bifurcation" in figures:
        add(f"![Bifurcation diagram]({figures['bifurcation']})")
        add("")
    add(
        "Black: the angle at each tachometer pulse (drive phase 0) in the settled part of every "
        f"sweep step. Blue and orange: the {model_name} model with the identified parameters, "
        "simulated over the same amplitudes "
        "with continuation upwards and downwards (coexisting attractors show as a difference "
        "between the two)."
    )
    add("")
    if result.sweep is not None:
        add("### The sweep explained as one")
        add("")
        add("One rig identified for every step, the causes that hold across the steps, and "
            "each model's bifurcation diagram simulated through the sweep as the rig ran it, "
            f"over the measured one (full analysis: [{result.sweep['page']}]"
            f"({result.sweep['page']})).")
        add("")
        for line in sweep_lines(result.sweep):
            add(f"- {line.strip()}")
        add("")
        for figure in result.sweep["figures"]:
            add(f"![{Path(figure).stem.replace('_', ' ')} over the measured one]({figure})")
            add("")
    add("## What the virtual rig hid")
    add("")
    add(f"The virtual rig ran with: **{result.hidden.describe()}**.")
    add("")
    for name, cause in result.findings.items():
        verdict = "matches" if cause == result.hidden.name else "differs"
        add(f"- {name.replace('_', ' ')}: the analysis named **{cause}** ({verdict})")
    add("")
    if result.notes:
        add("## Notes")
        add("")
        for note in result.notes:
            add(f"- {note}")
        add("")
    add("## Files")
    add("")
    add("- `parameters.json`: identified parameters (docs/MODEL.md section 7 keys) and the "
        "true ones")
    add("- `identify_free_decay.json`, `identify_impact_decay.json`: the identification reports")
    add("- `analysis/*.md` (or `.html`), `analysis/*.json`: discrepancy analysis of each record "
        "(docs/MODEL.md section 6) with its figures")
    add("- `sweep_regimes.json`, `bifurcation.json`: regimes and diagram data")
    add("- `demo.json`: settings, timings and a summary of all of the above")
    add("")
    timing = ", ".join(f"{k} {v:.1f} s" for k, v in result.timings_s.items())
    add(f"Timings: {timing}.")
    lines += markdown_provenance()
    return write_page(lines, result.report)


def _value(estimate: Mapping[str, Any] | None) -> str:
    return "-" if not estimate else f"{estimate['value']:.6g}"


def _interval(estimate: Mapping[str, Any] | None, truth: float | None) -> str:
    if not estimate:
        return "-"
    ci = estimate.get("ci95")
    text = interval_text(estimate["value"], ci)
    if not interval_determined(estimate["value"], ci):
        return text
    if truth is not None and not ci[0] <= truth <= ci[1]:
        text += " *misses*"
    return text


def _num(value: Any) -> str:
    if value is None:
        return "-"
    try:
        return f"{float(value):.3g}"
    except (TypeError, ValueError):
        return str(value)


def write_demo_json(path: Path, data: Mapping[str, Any], *, overwrite: bool) -> Path:
    """One of the demo's JSON files: ``data`` and the provenance (an existing file is refused
    unless ``overwrite``)."""
    return write_json(path, {**data, "provenance": provenance()}, overwrite=overwrite)


def write_identifications(
    folder: Path,
    identified: Mapping[str, IdentificationResult],
    records: Mapping[str, Any],
    *,
    overwrite: bool,
) -> None:
    """identify_NAME.json: each identification's report, naming the record it came from."""
    for name, result in identified.items():
        report = {**result.as_json(), "source": str(records[name].source)}
        write_demo_json(folder / f"identify_{name}.json", report, overwrite=overwrite)


def write_analyses(
    folder: Path, analyses: Mapping[str, Analysis], *, overwrite: bool
) -> dict[str, Path]:
    """Each discrepancy analysis's page (Markdown, JSON and figures) in the folder's
    analysis/; the pages' paths relative to the folder, by record."""
    from analysis.report import write_report as write_analysis_report

    return {
        name: write_analysis_report(analysis, folder / ANALYSIS, name=name, overwrite=overwrite)
        .relative_to(folder)
        for name, analysis in analyses.items()
    }


def bifurcation_json(
    model: Model, frequency_hz: float, diagrams: Sequence[BifurcationDiagram]
) -> dict[str, Any]:
    """bifurcation.json: the identified model and each diagram's points (the angles a
    parameter value reached, without the padding of those that reached fewer)."""
    return {
        q.frequency_hz: frequency_hz,
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
    }


def demo_json(
    result: DemoResult, settings: DemoSettings, recordings: Mapping[str, Any]
) -> dict[str, Any]:
    """demo.json: the settings, the hidden and the found causes, the recordings and timings."""
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
        "sweep": result.sweep,
        "timings_s": result.timings_s,
        "notes": result.notes,
    }
