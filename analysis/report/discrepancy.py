"""Write a discrepancy analysis as JSON and as a page (Markdown and HTML) with PNG figures.

Figures: the record with the baseline and the extended model, the residuals of
both, and for impact decays the constant-restitution model against Hunt-Crossley.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from analysis import quantities as q
from analysis.discrepancy.fitting import predict
from analysis.discrepancy.outcome import Analysis
from analysis.estimate_text import interval_text
from analysis.extensions import BASELINE, NONE
from analysis.figure_style import legend_beside, save_figure
from analysis.json_output import json_ready, write_json
from analysis.provenance import markdown_provenance, provenance
from analysis.report.pages import write_page


def report_json(analysis: Analysis) -> dict[str, Any]:
    """The analysis as its JSON report holds it: plain values, a number that is not finite as
    None (the rule of analysis.json_output)."""
    return json_ready(analysis.as_json())


def write_analysis_json(analysis: Analysis, path: str | Path, *, overwrite: bool = False) -> Path:
    """Write the JSON report, with its provenance; returns its path (an existing file is
    refused unless ``overwrite``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_json(path, {**report_json(analysis), "provenance": provenance()},
                      overwrite=overwrite)


def figure_fit(analysis: Analysis, path: Path) -> Path:
    """Record, baseline and extended model (top); residuals before and after (bottom)."""
    data = analysis.data
    base, ext = analysis.model_curves()
    best = analysis.shown_model
    label = best.model.name if best is not None else NONE
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.2), sharex=True)
    t = data.t
    ax = axes[0]
    ax.plot(t, data.y, ".", ms=1.5, color="0.4", label="measured")
    ax.plot(t, base, lw=0.8, color="tab:red", label="baseline")
    if ext is not None:
        ax.plot(t, ext, lw=0.8, ls="--", color="tab:blue", label=f"+ {label}")
    ax.set_ylabel("angle [rad]")
    legend_beside(ax, fontsize=8)
    if analysis.n_train < t.size:
        for a in axes:
            a.axvline(t[analysis.n_train], color="0.6", lw=0.6, ls=":")
    adopted = analysis.final_outcome
    title = adopted.model.name if adopted is not None else NONE
    ax.set_title(f"{data.experiment}: {'causes' if '+' in title else 'cause'} = {title}",
                 fontsize=10)
    ax = axes[1]
    ax.plot(t, base - data.y, lw=0.6, color="tab:red", label="baseline residual")
    if ext is not None:
        ax.plot(t, ext - data.y, lw=0.6, color="tab:blue", label=f"+ {label} residual")
    ax.axhline(0, color="0.5", lw=0.5)
    ax.set_xlabel("time [s]  (dotted: end of the fitted part for the held-out test)")
    ax.set_ylabel("model - data [rad]")
    legend_beside(ax, fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
    return path


def figure_restitution(analysis: Analysis, path: Path) -> Path:
    """Constant-restitution and Hunt-Crossley fits of an impact decay."""
    data = analysis.data
    base, _ = predict(data, BASELINE, analysis.baseline.values)
    rest = analysis.restitution or {}
    fig, axes = plt.subplots(2, 1, figsize=(8, 5.2), sharex=True)
    axes[0].plot(data.t, data.y, ".", ms=1.5, color="0.4", label="measured")
    axes[0].plot(data.t, base, lw=0.8, color="tab:red", label="Hunt-Crossley contact")
    axes[0].plot(data.t, rest["curve"], lw=0.8, ls="--", color="tab:green",
                 label="constant restitution e")
    axes[0].set_ylabel("angle [rad]")
    legend_beside(axes[0], fontsize=8)
    axes[1].plot(data.t, base - data.y, lw=0.6, color="tab:red", label="Hunt-Crossley")
    axes[1].plot(data.t, rest["residual"], lw=0.6, color="tab:green", label="restitution")
    axes[1].set_ylabel("model - data [rad]")
    axes[1].set_xlabel("time [s]")
    legend_beside(axes[1], fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
    return path


def _fmt(est: dict[str, Any]) -> str:
    value = est.get("value")
    ci = est.get("ci95")
    if value is None:
        return "-"
    return f"{value:.4g} {interval_text(value, ci, '.4g')}"


def _parameters_story(js: dict[str, Any]) -> str:
    """Why this page's baseline values need not equal ``identify``'s or the demo's: which
    data and which model each column comes from."""
    method = ("multiple shooting over linked segments of the whole record"
              if js["experiment"] == "forced" else "one simulation from the release")
    prepared = "; ".join(n for n in js.get("notes", []) if "sample" in n or "release" in n)
    extended = js["extended"]["cause"]
    return (
        f"Both columns are fitted by this analysis to the record as prepared for it "
        f"({js['samples_fitted']} samples{'; ' + prepared if prepared else ''}) by {method}. "
        "`impact-rig identify` fits the baseline to the record with its own method and data "
        "(every sample, and for an impact decay the free decay's L and zeta held), so its "
        "values may differ within their intervals. "
        + (f"The extended model adds `{extended}`: where the baseline bent its own parameters "
           "to make up for the missing effect, the two columns differ by that bend."
           if extended != NONE else "No cause was found: the extended model is the baseline.")
    )


def write_report(
    analysis: Analysis, directory: str | Path, name: str = "report", *, overwrite: bool = False
) -> Path:
    """Write NAME.md, NAME.html, NAME.json and the PNG figures into ``directory``; returns
    the .md path.
    An existing NAME.json is refused unless ``overwrite`` (checked first, before the rest)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    js = report_json(analysis)
    write_analysis_json(analysis, directory / f"{name}.json", overwrite=overwrite)
    fit_png = figure_fit(analysis, directory / f"{name}_fit.png")
    lines = [
        f"# Discrepancy analysis: {Path(analysis.record.source).name or 'record'}",
        "",
        f"- experiment: `{js['experiment']}`",
        "- **causes: " + ", ".join(
            f"`{c['cause']}` (BIC gain {c['gain']['information_criterion_delta']:.4g})"
            for c in js["causes"]) + "**" if len(js["causes"]) > 1
        else f"- **cause: `{js['cause']}`**",
        f"- where the baseline fails: {js['localization']}",
        f"- baseline rms residual {js['baseline']['rms_residual']:.3g} rad; extended "
        f"{js['extended']['rms_residual']:.3g} rad (noise {js['noise_rad']:.3g} rad)",
    ]
    if js.get("regime"):
        lines.append(f"- regime judged from the record: {js['regime']['label']}")
    if js.get("drive"):
        d = js["drive"]
        lines.append(
            f"- drive: {d[q.frequency_hz]:.6g} Hz from the {d['frequency_source']} (stated "
            f"{d['stated'][q.frequency_hz]:.6g} Hz), phase from the {d['phase_source']}"
        )
    if js.get("comparison") == "invariant statistics":
        lines.append(
            "- chaotic response: candidates judged on invariant statistics (Poincare section, "
            "turning points, spectral lines), not point by point; ranking's verdicts give each "
            "one's invariant-distance ratio"
        )
    lines += [f"- **caution:** {w}" for w in js.get("warnings", [])]
    lines += [f"- **cannot tell apart:** {pair['why']}" for pair in js.get("indistinct", [])]
    lines += [f"- residual finding ({f['kind']}): {f['text']}"
              for f in js.get("residual_findings", [])]
    lines += [f"- {term['text']}" for term in js.get("proposed_terms", [])]
    gain = js["gain"]
    if gain["heldout_rms_baseline"] is not None:
        lines.append(
            f"- held-out prediction ({js['heldout']}): baseline "
            f"{gain['heldout_rms_baseline']:.3g} rad, extended "
            f"{(gain['heldout_rms_extended'] or 0):.3g} rad; BIC gain "
            f"{gain['information_criterion_delta']:.4g}"
        )
    lines += ["", f"![fit and residuals]({fit_png.name})", "", "## Ranking", "",
              "| cause | score (BIC gain) | held-out ratio | rms [rad] | parameters | earns keep |",
              "|---|---|---|---|---|---|"]
    for row in js["ranking"]:
        params = ", ".join(f"{k} = {_fmt(v)}" for k, v in row["parameters"].items())
        ratio = row["heldout_ratio"]
        lines.append(
            f"| {row['cause']} | {row['score']:.4g} | "
            f"{'-' if ratio is None else f'{ratio:.3g}'} | {row['rms_residual']:.3g} | "
            f"{params} | {'yes' if row['earns_keep'] else 'no'} |"
        )
    if js.get("excluded"):
        lines += ["", "Causes that cannot show in this experiment:", ""]
        lines += [f"- `{k}`: {v}" for k, v in js["excluded"].items()]
    lines += ["", "## Parameters", "", _parameters_story(js), "",
              "| key | baseline | extended |", "|---|---|---|"]
    keys = list(dict.fromkeys([*js["baseline"]["parameters"], *js["extended"]["parameters"]]))
    for k in keys:
        b = js["baseline"]["parameters"].get(k)
        e = js["extended"]["parameters"].get(k)
        lines.append(f"| {k} | {_fmt(b) if b else '-'} | {_fmt(e) if e else '-'} |")
    if analysis.restitution is not None:
        rc = js["restitution_comparison"]
        rest_png = figure_restitution(analysis, directory / f"{name}_restitution.png")
        lines += [
            "", "## Finite-time contact against a constant coefficient of restitution", "",
            "The classical model treats each impact as instantaneous: the velocity is reversed "
            "and multiplied by a constant e at the barrier, the pendulum swings freely between "
            "impacts. Hunt-Crossley contact lets the restitution depend on the impact speed "
            "and gives the contact a duration.",
            "",
            f"- constant e = {_fmt(rc['parameters'][q.e])}: rms residual "
            f"{rc['rms_residual']:.3g} rad, held-out {rc['heldout_rms']:.3g} rad",
            f"- Hunt-Crossley: rms residual {rc['hunt_crossley_rms_residual']:.3g} rad, held-out "
            f"{rc['hunt_crossley_heldout_rms']:.3g} rad",
            f"- rms reduction by Hunt-Crossley {100 * rc['rms_reduction_by_hunt_crossley']:.3g} %,"
            f" BIC gain {rc['information_criterion_delta_for_hunt_crossley']:.4g}",
            "", f"![restitution]({rest_png.name})",
        ]
    if js.get("notes"):
        lines += ["", "## Notes", ""] + [f"- {n}" for n in js["notes"]]
    lines += ["", f"Rules: {analysis.policy.summary()}."]
    lines += markdown_provenance()
    return write_page(lines, directory / f"{name}.md")
