"""The demo's stages in order: prepare, record on the virtual rig, identify, judge the sweep's
regimes, explain the discrepancies (each record, then the sweep as one), draw the
bifurcation diagram and write the report."""

from __future__ import annotations

import time
from pathlib import Path

from analysis.progress import ProgressText
from rig.config import load_config
from rig.demo.analyse import (
    analyse_discrepancies,
    bifurcation_diagrams,
    classify_steps,
    combined_parameters,
    explain_sweep,
    explained_parameters,
    identified_model,
    identify,
    load_records,
    sweep_candidates,
)
from rig.demo.record import (
    demo_config,
    prepare_folder,
    record_everything,
    true_values,
    warm_up_physics,
)
from rig.demo.report import (
    DemoResult,
    bifurcation_json,
    demo_json,
    write_analyses,
    write_demo_json,
    write_figures,
    write_identifications,
    write_report,
    write_sweep_explanation,
)
from rig.demo.settings import (
    DEFAULT_CAUSE,
    DEFAULT_CAUSE_VALUES,
    FULL,
    REPORT_NAME,
    DemoSettings,
    HiddenCause,
    hidden_cause,
)


def run_demo(
    folder: str | Path,
    *,
    settings: DemoSettings = FULL,
    hidden: HiddenCause | None = None,
    config_path: str | Path | None = None,
    overwrite: bool = False,
    progress: ProgressText | None = None,
) -> DemoResult:
    """Record, identify, explain and report on the virtual rig; returns what was found."""
    say = progress or (lambda text: None)
    hidden = hidden or hidden_cause(DEFAULT_CAUSE, DEFAULT_CAUSE_VALUES)
    clock = time.monotonic()
    timings: dict[str, float] = {}
    notes: list[str] = []
    folder = prepare_folder(folder, overwrite=overwrite)
    config = demo_config(load_config(config_path), hidden)
    truth = {**true_values(config), **hidden.values}  # a hidden cause sets its own values

    def lap(name: str) -> None:
        timings[name] = round(time.monotonic() - clock - sum(timings.values()), 2)

    say("[1/6] preparing the compiled physics (slow only the first time after install) ...")
    warm_up_physics(config)
    lap("warm_up")
    say(
        f"[2/6] recording on the virtual rig (pty serial DAQ + Modbus TCP amplifier, "
        f"{settings.virtual_speed:g}x real time, {settings.sample_rate_hz:g} Hz)"
    )
    results = record_everything(config, folder, settings, say)
    lap("recording")
    for result in results.values():
        if result.samples_lost:
            notes.append(f"{result.path.name}: {result.samples_lost} samples lost")

    say("[3/6] identifying L, zeta (free decay), K, mu0 (impact decay)")
    records = load_records(results, notes)
    identified = identify(records, say)
    write_identifications(folder, identified, records, overwrite=overwrite)
    baseline = combined_parameters(identified)
    lap("identification")

    say("[4/6] judging the regime of every sweep step")
    regimes, sections = classify_steps(records["sweep_steps"], say)
    write_demo_json(folder / "sweep_regimes.json", {"steps": regimes}, overwrite=overwrite)
    lap("regimes")

    say("[5/6] discrepancy analysis (it is not told what the virtual rig hides)")
    analyses = analyse_discrepancies(records, regimes, baseline, settings, say, notes)
    pages = write_analyses(folder, analyses, overwrite=overwrite)
    parameters, causes = explained_parameters(baseline, analyses)
    write_demo_json(
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
        overwrite=overwrite,
    )
    lap("discrepancy")
    say("  the sweep as one: one rig for every step, the causes across its steps")
    sweep_analysis = explain_sweep(results["sweep"].path, say, notes,
                                   sweep_candidates(analyses, settings, notes))
    sweep = (None if sweep_analysis is None else
             write_sweep_explanation(folder, sweep_analysis, overwrite=overwrite))
    lap("sweep")

    say("[6/6] bifurcation diagram: measured sweep against the model; figures and report")
    rig = records["impact_decay"].rig_parameters()
    model = identified_model(parameters, rig, settings.sweep_frequency_hz, causes)
    diagrams = bifurcation_diagrams(model, settings, regimes, sections, say)
    write_demo_json(
        folder / "bifurcation.json",
        bifurcation_json(model, settings.sweep_frequency_hz, diagrams),
        overwrite=overwrite,
    )
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
        findings={name: analysis.chosen for name, analysis in analyses.items()},
        regimes=regimes,
        timings_s=timings,
        notes=notes,
        sweep=sweep,
    )
    write_report(result, settings, results, analyses, pages, figures, config)
    write_demo_json(folder / "demo.json", demo_json(result, settings, results), overwrite=overwrite)
    return result
