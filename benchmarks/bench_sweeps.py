"""Benchmark of sweeps explained where a lab looks: on their bifurcation diagrams (issue 33).

Each case draws (seeded) a sweep from the independent reference simulator
(``reference/sweeps.py``: scipy DOP853 with events, never the project's integrator):
over the amplitude at 6 Hz or the frequency over 4-7 Hz, up and back down, each step
settled (8 s) and dwelt on (6 s), the state continued from step to step; noise to 2 mrad,
the table's laser on some; one hidden cause per sweep, cycling through those that move the
diagram, those that only distort the reading, and none.

For each sweep the true model (the rig with its hidden cause) and the baseline (the rig
without it) are simulated through the sweep as the rig ran it with the project's compiled
simulator and compared with the measured diagram step by step
(:mod:`analysis.sweep.diagram`): the steps agreeing on their regime and the distance of the
stroboscopic clouds in units of the noise.  The sweep explanation (``analysis.sweep``'s
shared fit and its diagrams) is called at the place marked EXPLANATION below and scored:
the hidden cause named with its parameters within their 95 % intervals, no cause on the
clean sweeps, and the explained model's regime on the steps the fitted baseline's
diagram gets wrong.

The figures say whether the issue's bar is met (``done_when``): on at least 12 sweeps of at
least 10 steps, the hidden cause named with its parameters within their 95 % intervals on
90 % or more of the sweeps with one, no cause named on the clean sweeps, and the explained
model's regime agreeing with the measured one on 90 % or more of the steps the fitted
baseline gets wrong.

Two timings, each with 1 and with 2 workers on the ``impact-rig map`` Dask path, as a ratio
measured in one process: simulating a 16-step sweep of 20 s steps (8 s settle, 12 s dwell)
for the baseline and the true model; and explaining a drawn 16-step sweep of 20 s steps
whole, as ``impact-rig analyze SWEEP --workers N`` does (its fits on N threads, its
diagrams on N workers), with whether the two explanations' reports are the same.

    python benchmarks/bench_sweeps.py                       # 12 sweeps of 11 steps
    python benchmarks/bench_sweeps.py --sweeps 2 --up-steps 3 --json sweeps.json --overwrite
    python benchmarks/bench_sweeps.py --timing-only
    python benchmarks/bench_sweeps.py --timing-only --no-explanation-timing   # simulation only
    python benchmarks/bench_sweeps.py --save    # also benchmarks/results/sweeps.json (the page)
    python benchmarks/bench_sweeps.py --sweeps 1 --up-steps 2 --settle 2 --dwell 3 \\
        --timing-steps 2 --timing-settle 2 --timing-dwell 3       # the smallest, a smoke run
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.json_output import to_json_text, write_json
from analysis.maps import MapRunner
from analysis.records import Record
from analysis.report.sweep import sweep_report_json
from analysis.sweep.analyze import SweepAnalysis, analyze_sweep
from analysis.sweep.diagram import (
    DiagramComparison,
    JudgedStep,
    compare_diagrams,
    judge_measured,
)
from analysis.sweep.steps import DOWN, UP, Sweep, SweepStep
from harness.results import figure, result, save
from reference.sweeps import (
    AMPLITUDE_SWEEP_BETA,
    AMPLITUDE_SWEEP_HZ,
    DISTORTS_READING,
    FREQUENCY_SWEEP_HZ,
    MOVES_DIAGRAM,
    PARAMETERS,
    draw_sweep,
    sweep_of,
    sweep_visibility,
    truth_model,
)
from reference.visibility import Visibility

CAUSE_CYCLE = ("none", *MOVES_DIAGRAM, *DISTORTS_READING)
FIRST_SEED = 3300
TIMING_STEPS = 16
TIMING_SETTLE_S, TIMING_DWELL_S = 8.0, 12.0
TIMING_SEED = 3390  # the sweep whose explanation is timed (an amplitude sweep, barrier offset)
# The bar (docs: issue 33, "Done when")
LEAST_SWEEPS, LEAST_STEPS, LEAST_SHARE = 12, 10, 0.9


def _draw(request: tuple[int, str, str, int, float, float]) -> tuple[Any, Any, float]:
    """One sweep drawn in a worker process: its truth and channels (they pickle), and the
    seconds it took."""
    seed, cause, parameter, up_steps, settle_s, dwell_s = request
    clock = time.perf_counter()
    generated = draw_sweep(seed, cause, parameter=parameter, up_steps=up_steps,
                           settle_s=settle_s, dwell_s=dwell_s)
    return generated.truth, generated.run, time.perf_counter() - clock


def _draw_judged(request: tuple[int, str, str, int, float, float]
                 ) -> tuple[Any, Any, float, Visibility | None]:
    """:func:`_draw`, and how much of its hidden cause shows in its noiseless readings
    after the baseline refits its own parameters (None for a clean sweep)."""
    truth, run, seconds = _draw(request)
    return truth, run, seconds, (None if truth.cause == "none"
                                 else sweep_visibility(truth, run))


def explain(sweep: Sweep) -> SweepAnalysis:
    """EXPLANATION: the sweep's analysis (``analysis.sweep.analyze``): one rig, the causes
    named across the steps, and its baseline's and explained model's diagrams."""
    return analyze_sweep(sweep)


def _explanation(truth: Any, analysis: SweepAnalysis) -> dict[str, Any]:
    """The explanation scored: the causes named, the hidden cause's parameters within
    their 95 % intervals, and the fitted baseline's and explained model's agreement
    (over every step, and on the steps the fitted baseline gets wrong)."""
    named = list(analysis.causes.named)
    estimates = analysis.causes.final.full.estimates
    within = None
    if truth.cause != "none" and truth.cause in named:
        checks = []
        for parameter, value in truth.causes[truth.cause].items():
            e = estimates.get(parameter)
            checks.append(e is not None and e.ci95 is not None
                          and e.ci95[0] <= value <= e.ci95[1])
        within = all(checks)
    diagrams = analysis.diagrams
    base = diagrams.baseline
    explained = diagrams.explained or base
    missed = [k for k, step in enumerate(base.steps)
              if not step.agrees and step.measured != "undetermined"]
    return {
        "named": named,
        "named_right": named == [] if truth.cause == "none" else truth.cause in named,
        "parameters_within_ci95": within,
        "fitted_baseline_agreeing": base.agreeing,
        "explained_agreeing": explained.agreeing,
        "baseline_missed_steps": len(missed),
        "explained_agreeing_where_baseline_missed": sum(explained.steps[k].agrees
                                                        for k in missed),
        "diagram_summary": diagrams.summary(),
    }


def _row(seed: int, truth: Any, seconds: float, visibility: Visibility | None,
         measured: tuple[JudgedStep, ...], true: DiagramComparison,
         baseline: DiagramComparison, explanation: dict[str, Any]) -> dict[str, Any]:
    def distance(comparison: DiagramComparison) -> float:
        values = [s.distance for s in comparison.steps if math.isfinite(s.distance)]
        return float(np.median(values)) if values else math.nan

    return {
        "seed": seed,
        "cause": truth.cause,
        "moves_diagram": truth.moves_diagram,
        "parameter": truth.parameter,
        # how much of the hidden cause the readings show (reference.sweeps.sweep_visibility);
        # a cause that shows less than SHOWS_OVER_NOISE is not identifiable on this sweep
        "cause_effect_over_noise": None if visibility is None else visibility.effect_over_noise,
        "cause_visible_over_noise": (None if visibility is None
                                     else visibility.visible_over_noise),
        "identifiable": None if visibility is None else visibility.shows,
        "steps": len(true.steps),
        "laser": truth.measurement.laser,
        "noise_rad": truth.measurement.angle_noise_rad,
        "measured": [m.short for m in measured],
        "true_agreeing": true.agreeing,
        "baseline_agreeing": baseline.agreeing,
        "true_median_distance": distance(true),
        "baseline_median_distance": distance(baseline),
        "true_summary": true.summary(),
        "baseline_summary": baseline.summary(),
        **explanation,
        "generation_s": seconds,
    }


def _timing_sweep(truth: Any, steps: int = TIMING_STEPS, settle_s: float = TIMING_SETTLE_S,
                  dwell_s: float = TIMING_DWELL_S) -> tuple[Sweep, tuple[JudgedStep, ...]]:
    """A sweep of ``steps`` steps (by default 16 of 20 s: 8 up over the generator's range
    for the swept parameter, 8 back down) on the rig of ``truth``, at 1 kHz: records of the
    right length (the timing simulates them; nothing is compared), each step judged with a
    stated noise of 1 mrad."""
    fs = truth.sample_rate_hz
    rising = (steps + 1) // 2
    if truth.parameter == "amplitude":
        up = [(AMPLITUDE_SWEEP_HZ, float(beta) * truth.rig.L_m)
              for beta in np.linspace(*AMPLITUDE_SWEEP_BETA, rising)]
    else:
        amplitude = truth.drives[0].stated_amplitude_m
        up = [(float(f), amplitude) for f in np.linspace(*FREQUENCY_SWEEP_HZ, rising)]
    samples = round(dwell_s * fs)
    rig = {"m_kg": truth.rig.m_kg, "l_m": truth.rig.l_m, "R_m": truth.rig.R_m,
           "g": truth.rig.g_m_s2}
    made = []
    for number, (frequency, amplitude) in enumerate((up + up[::-1])[:steps]):
        record = Record(time_s=np.arange(samples) / fs, angle_rad=np.zeros(samples),
                        experiment="forced", rig=rig,
                        drive={"frequency_hz": frequency, "amplitude_m": amplitude},
                        source=f"timing step {number}")
        made.append(SweepStep(number, UP if number < len(up) else DOWN, frequency, amplitude,
                              settle_s, record))
    judged = tuple(JudgedStep(s.number, "undetermined", None, "", 1e-3, np.zeros((0, 8)),
                              np.zeros((0, 8))) for s in made)
    return Sweep("timing", truth.parameter, tuple(made)), judged


def time_workers(truth: Any, steps: int = TIMING_STEPS, settle_s: float = TIMING_SETTLE_S,
                 dwell_s: float = TIMING_DWELL_S) -> dict[str, float]:
    """Seconds to simulate (and judge) the timing sweep (:func:`_timing_sweep`) for the
    baseline and the true model with 1 worker (this process) and with 2 (a local Dask
    cluster, its start not counted)."""
    sweep, judged = _timing_sweep(truth, steps, settle_s, dwell_s)
    start = (truth.theta0_rad, truth.theta_dot0_rad_s)
    cases = [(name, model, sweep, judged, start)
             for name, model in (("baseline", truth_model(truth, with_cause=False)),
                                 ("true", truth_model(truth)))]
    compare_diagrams(cases[:1])  # the compiled kernels loaded once before timing
    clock = time.perf_counter()
    one = compare_diagrams(cases)
    one_s = time.perf_counter() - clock
    with MapRunner(workers=2) as runner:
        runner.map(len, [()] * 2)  # the workers up and warm
        clock = time.perf_counter()
        two = compare_diagrams(cases, runner.map)
        two_s = time.perf_counter() - clock
    same = all(np.array_equal(a.theta_rad, b.theta_rad)
               for x, y in zip(one, two, strict=True)
               for a, b in zip(x.simulated, y.simulated, strict=True))
    return {"one_worker_s": one_s, "two_workers_s": two_s, "speed_up": one_s / two_s,
            "same_results": same}


def time_explanation(steps: int = TIMING_STEPS, settle_s: float = TIMING_SETTLE_S,
                     dwell_s: float = TIMING_DWELL_S) -> dict[str, Any]:
    """Seconds to explain a drawn sweep of ``steps`` steps whole (an amplitude sweep with a
    barrier offset, up and down, cut after its ``steps``-th step as an interrupted sweep is)
    as ``impact-rig analyze --workers N`` does, with N = 1 (this process) and N = 2 (a
    local Dask cluster, its start not counted), and whether both reports are the same."""
    generated = draw_sweep(TIMING_SEED, "barrier_offset", parameter="amplitude",
                           up_steps=steps // 2 + 1, settle_s=settle_s, dwell_s=dwell_s)
    sweep = replace(generated.sweep, steps=generated.sweep.steps[:steps])
    seconds, reports = {}, {}
    for workers in (1, 2):
        with MapRunner(workers=workers) as runner:
            runner.map(len, [()] * workers)  # the workers up and warm
            clock = time.perf_counter()
            analysis = analyze_sweep(sweep, threads=workers, run_map=runner.map)
            seconds[workers] = time.perf_counter() - clock
        report = sweep_report_json(analysis)
        report["sweep"].pop("timings_s", None)
        reports[workers] = to_json_text(report)
    return {"steps": len(sweep.steps), "settle_s": settle_s, "dwell_s": dwell_s,
            "one_worker_s": seconds[1], "two_workers_s": seconds[2],
            "speed_up": seconds[1] / seconds[2], "same_results": reports[1] == reports[2]}


def _timings(args: argparse.Namespace, truth: Any) -> dict[str, Any]:
    """Both timings (see the module's docstring) at the asked size, the explanation's
    unless ``--no-explanation-timing``."""
    size = (args.timing_steps, args.timing_settle, args.timing_dwell)
    name = f"{size[0]}_steps_of_{size[1] + size[2]:g}_s"
    out = {f"timing_{name}": time_workers(truth, *size)}
    if not args.no_explanation_timing:
        out[f"explanation_{name}"] = time_explanation(*size)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=int, default=12)
    parser.add_argument("--up-steps", type=int, default=6, help="steps up (down: one fewer)")
    parser.add_argument("--settle", type=float, default=8.0, help="settle per step [s]")
    parser.add_argument("--dwell", type=float, default=6.0, help="dwell per step [s]")
    parser.add_argument("--jobs", type=int, default=2, help="processes drawing the sweeps")
    parser.add_argument("--no-timing", action="store_true", help="skip the worker timing")
    parser.add_argument("--timing-only", action="store_true", help="only the worker timing")
    parser.add_argument("--no-explanation-timing", action="store_true",
                        help="time the simulated sweep only, not its whole explanation")
    parser.add_argument("--timing-steps", type=int, default=TIMING_STEPS,
                        help="steps of the timed sweeps")
    parser.add_argument("--timing-settle", type=float, default=TIMING_SETTLE_S,
                        help="their settle per step [s]")
    parser.add_argument("--timing-dwell", type=float, default=TIMING_DWELL_S,
                        help="their dwell per step [s]")
    parser.add_argument("--json", type=Path, help="write the rows and figures here")
    parser.add_argument("--overwrite", action="store_true", help="replace the --json file")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/sweeps.json")
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    if args.json and args.json.exists() and not args.overwrite:
        parser.error(f"{args.json}: exists; pass --overwrite to replace it")
    requests = [(FIRST_SEED + k, CAUSE_CYCLE[k % len(CAUSE_CYCLE)],
                 PARAMETERS[k % len(PARAMETERS)], args.up_steps, args.settle, args.dwell)
                for k in range(args.sweeps)]
    figures: dict[str, Any] = {}
    if args.timing_only:  # the rig of a small sweep: the timing needs no measured steps
        truth = _draw((FIRST_SEED, "barrier_offset", "amplitude", 2, 0.5, 1.0))[0]
        figures |= _timings(args, truth)
        print(to_json_text(figures))
        _write(args, figures, [])
        _save(args, figures, load, [])
        return 0
    clock = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        # each sweep compared as soon as it is drawn; the figures written after each one
        for (seed, *_), (truth, run, seconds, visibility) in zip(
                requests, pool.map(_draw_judged, requests), strict=True):
            rows.append(_compare(seed, truth, run, seconds, visibility))
            figures = _figures(rows)
            _write(args, figures, rows)
    print(f"{len(rows)} sweeps drawn by the reference simulator and compared in "
          f"{time.perf_counter() - clock:.0f} s ({args.jobs} processes drawing)")
    if not args.no_timing:
        figures |= _timings(args, truth)
    print(to_json_text(figures))
    _write(args, figures, rows)
    _save(args, figures, load, rows)
    return 0


def _compare(seed: int, truth: Any, run: Any, seconds: float,
             visibility: Visibility | None) -> dict[str, Any]:
    """One drawn sweep's row: the true model and the baseline against its diagram, and the
    explanation's named causes."""
    sweep = sweep_of(truth, run)
    measured = judge_measured(sweep)
    start = (truth.theta0_rad, truth.theta_dot0_rad_s)
    true, baseline = compare_diagrams([
        ("true", truth_model(truth), sweep, measured, start),
        ("baseline", truth_model(truth, with_cause=False), sweep, measured, start)])
    try:
        explanation = _explanation(truth, explain(sweep))  # EXPLANATION
    except Exception as error:  # a failed explanation is a figure, not the end of the run
        explanation = {"named": None, "named_right": False, "parameters_within_ci95": None,
                       "fitted_baseline_agreeing": None, "explained_agreeing": None,
                       "baseline_missed_steps": 0,
                       "explained_agreeing_where_baseline_missed": 0,
                       "diagram_summary": f"the explanation failed: {error}",
                       "explanation_error": f"{type(error).__name__}: {error}"}
    row = _row(seed, truth, seconds, visibility, measured, true, baseline, explanation)
    print(f"seed {seed} {truth.parameter:9s} {truth.cause:22s} measured "
          f"{' '.join(row['measured'])}")
    if visibility is not None:
        print(f"    the cause shows {visibility.visible_over_noise:.3g} x the noise after the "
              f"baseline's refit (of {visibility.effect_over_noise:.3g}): "
              f"{'identifiable' if visibility.shows else 'NOT identifiable'}")
    print(f"    {true.summary()}; median distance {row['true_median_distance']:.3g}")
    print(f"    {baseline.summary()}; median distance {row['baseline_median_distance']:.3g}"
          + f"; explanation names {row['named'] or 'nothing'}")
    print(f"    explanation: {row['diagram_summary']}", flush=True)
    return row


def _write(args: argparse.Namespace, figures: dict[str, Any],
           rows: list[dict[str, Any]]) -> None:
    if args.json:
        write_json(args.json, {"made_by": "benchmarks/bench_sweeps.py", "command": sys.argv,
                               "figures": figures, "rows": rows}, overwrite=True)


def _figures(rows: list[dict[str, Any]]) -> dict[str, Any]:
    steps = sum(r["steps"] for r in rows)
    moving = [r for r in rows if r["moves_diagram"]]
    hidden = [r for r in rows if r["cause"] != "none"]
    clean = [r for r in rows if r["cause"] == "none"]
    return {
        "sweeps": len(rows),
        "steps": steps,
        "true_model_steps_agreeing": sum(r["true_agreeing"] for r in rows) / steps,
        "baseline_steps_agreeing": sum(r["baseline_agreeing"] for r in rows) / steps,
        "moving_causes": {
            "sweeps": len(moving),
            "true_steps_agreeing": (sum(r["true_agreeing"] for r in moving)
                                    / max(1, sum(r["steps"] for r in moving))),
            "baseline_steps_agreeing": (sum(r["baseline_agreeing"] for r in moving)
                                        / max(1, sum(r["steps"] for r in moving))),
            "true_median_distance": float(np.median([r["true_median_distance"]
                                                     for r in moving])) if moving else None,
            "baseline_median_distance": float(np.median([r["baseline_median_distance"]
                                                         for r in moving])) if moving else None,
        },
        "steps_undetermined_measured": sum(m == "undetermined" for r in rows
                                           for m in r["measured"]) / steps,
        # of the steps whose measured regime is determined (an undetermined one agrees with
        # no model)
        "true_model_judged_steps_agreeing": sum(r["true_agreeing"] for r in rows) / max(
            1, sum(m != "undetermined" for r in rows for m in r["measured"])),
        "baseline_judged_steps_agreeing": sum(r["baseline_agreeing"] for r in rows) / max(
            1, sum(m != "undetermined" for r in rows for m in r["measured"])),
        "explanation": {
            "hidden_cause_named": _share([r["named_right"] for r in hidden]),
            "hidden_cause_named_within_ci95": _share([bool(r["parameters_within_ci95"])
                                                      for r in hidden]),
            # the sweeps whose cause shows in the readings (reference.sweeps.sweep_visibility)
            "identifiable_sweeps": sum(bool(r.get("identifiable")) for r in hidden),
            "identifiable_named_within_ci95": _share([bool(r["parameters_within_ci95"])
                                                      for r in hidden if r.get("identifiable")]),
            "clean_sweeps_no_cause": _share([r["named_right"] for r in clean]),
            "explained_agreeing_where_baseline_missed": (
                sum(r["explained_agreeing_where_baseline_missed"] for r in rows)
                / max(1, sum(r["baseline_missed_steps"] for r in rows))),
            "baseline_missed_steps": sum(r["baseline_missed_steps"] for r in rows),
            "failed": sum("explanation_error" in r for r in rows),
        },
    } | {"done_when": _done_when(rows)}


def _done_when(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The issue's bar, each part with whether this run meets it (a run smaller than the
    issue's, or with no sweep of a kind, meets none of it); the hidden causes judged are
    the identifiable ones."""
    # a cause the sweep's readings do not show (reference.sweeps.sweep_visibility) is not
    # identifiable on it: reported among the hidden causes, not held against the bar
    hidden = [r for r in rows if r["cause"] != "none" and r.get("identifiable")]
    clean = [r for r in rows if r["cause"] == "none"]
    missed = sum(r["baseline_missed_steps"] for r in rows)
    size = len(rows) >= LEAST_SWEEPS and min((r["steps"] for r in rows), default=0) >= LEAST_STEPS
    named = _share([r["named_right"] and bool(r["parameters_within_ci95"]) for r in hidden])
    quiet = _share([r["named_right"] for r in clean])
    regained = (sum(r["explained_agreeing_where_baseline_missed"] for r in rows) / missed
                if missed else None)
    return {
        "issue_size": size,
        "hidden_cause_named_within_ci95": named is not None and named >= LEAST_SHARE,
        "clean_sweeps_no_cause": quiet == 1.0,
        "explained_agreeing_where_baseline_missed":
            regained is not None and regained >= LEAST_SHARE,
        "met": bool(size and named is not None and named >= LEAST_SHARE and quiet == 1.0
                    and regained is not None and regained >= LEAST_SHARE),
    }


def _share(flags: list[bool]) -> float | None:
    return sum(flags) / len(flags) if flags else None


def _save(args: argparse.Namespace, figures: dict[str, Any], load: float,
          rows: list[dict[str, Any]]) -> None:
    """With ``--save``: the figures as rows of the benchmarks page (harness/results.py)."""
    if not args.save:
        return
    page = []
    if "sweeps" in figures:
        explanation = figures["explanation"]
        page = [
            figure("steps whose regime the true model / the baseline gets right",
                   f"{_percent(figures['true_model_steps_agreeing'])} / "
                   f"{_percent(figures['baseline_steps_agreeing'])} of {figures['steps']} "
                   f"steps ({_percent(figures['steps_undetermined_measured'])} undetermined "
                   "as measured)"),
            figure("hidden cause named; its parameters within their 95 % intervals",
                   f"{_percent(explanation['hidden_cause_named'])}; "
                   f"{_percent(explanation['hidden_cause_named_within_ci95'])}; on the "
                   f"{explanation['identifiable_sweeps']} sweeps whose cause shows, within: "
                   f"{_percent(explanation['identifiable_named_within_ci95'])}"
                   + _misses(rows),
                   f">= {_percent(LEAST_SHARE)} within, where the cause shows"),
            figure("clean sweeps with no cause named",
                   _percent(explanation["clean_sweeps_no_cause"]), "100 %"),
            figure("explained model right where the fitted baseline is wrong",
                   f"{_percent(explanation['explained_agreeing_where_baseline_missed'])} of "
                   f"{explanation['baseline_missed_steps']} steps", f">= {_percent(LEAST_SHARE)}"),
            figure("explanations failed", f"{explanation['failed']}/{figures['sweeps']}", "0"),
        ]
    timing = figures.get("timing_16_steps_of_20_s")
    if timing is not None:
        page.append(figure(
            "16 steps of 20 s, baseline and true model: 2 workers vs 1 (same results)",
            f"{timing['speed_up']:.2f}x faster"
            + ("" if timing["same_results"] else " (results DIFFER)")))
    if not page:
        print("no figures to save (no sweep and no timing)")
        return
    about = ("only the worker timing" if args.timing_only else
             f"{args.sweeps} sweeps from the independent reference simulator, "
             "`reference/sweeps.py`, one hidden cause each or none")
    save(result("sweeps", page, about=about, load_at_start=load))


def _misses(rows: list[dict[str, Any]]) -> str:
    """The hidden causes missed, each as ' (misses: seed 3308 sensor_lag named none, ...)',
    with how much of a cause not identifiable shows."""
    misses = []
    for r in rows:
        if r["cause"] == "none" or (r["named_right"] and r["parameters_within_ci95"]):
            continue
        what = ("named with its parameters outside their intervals" if r["named_right"]
                else f"named {', '.join(r['named'] or []) or 'none'}")
        if r.get("identifiable") is False:
            what += (f"; not identifiable, {r['cause_visible_over_noise']:.2g} x the noise "
                     "shows after the baseline's refit")
        misses.append(f"seed {r['seed']} {r['cause']} {what}")
    return f" (misses: {'; '.join(misses)})" if misses else ""


def _percent(share: float | None) -> str:
    return "-" if share is None else f"{100 * share:.0f} %"


if __name__ == "__main__":
    raise SystemExit(main())
