"""Benchmark of sweeps explained where a lab looks: on their bifurcation diagrams (issue 33).

Each case draws (seeded) a sweep from the independent reference simulator
(``tests/reference/sweeps.py``: scipy DOP853 with events, never the project's integrator):
over the amplitude at 6 Hz or the frequency over 4-7 Hz, up and back down, each step
settled (8 s) and dwelt on (6 s), the state continued from step to step; noise to 2 mrad,
the table's laser on some; one hidden cause per sweep, cycling through those that move the
diagram, those that only distort the reading, and none.

For each sweep the true model (the rig with its hidden cause) and the baseline (the rig
without it) are simulated through the sweep as the rig ran it with the project's compiled
simulator and compared with the measured diagram step by step
(:mod:`analysis.sweep.diagram`): the steps agreeing on their regime and the distance of the
stroboscopic clouds in units of the noise.  The sweep explanation (``analysis.sweep``'s
shared fit, another branch) is called at the place marked EXPLANATION below and its named
causes scored when it is there.

Also the time of simulating a 16-step sweep of 20 s steps (8 s settle, 12 s dwell) for the
baseline and the true model, with 1 and with 2 workers (the ``impact-rig map`` Dask path),
as a ratio measured in one process.

    python benchmarks/bench_sweeps.py                       # 12 sweeps of 11 steps
    python benchmarks/bench_sweeps.py --sweeps 2 --up-steps 3 --json sweeps.json --overwrite
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.json_output import to_json_text, write_json
from analysis.maps import MapRunner
from analysis.records import Record
from analysis.sweep.diagram import (
    DiagramComparison,
    JudgedStep,
    compare_diagrams,
    judge_measured,
)
from analysis.sweep.steps import DOWN, UP, Sweep, SweepStep
from tests.reference.sweeps import (
    DISTORTS_READING,
    MOVES_DIAGRAM,
    PARAMETERS,
    draw_sweep,
    sweep_of,
    truth_model,
)

CAUSE_CYCLE = ("none", *MOVES_DIAGRAM, *DISTORTS_READING)
FIRST_SEED = 3300
TIMING_STEPS = 16
TIMING_SETTLE_S, TIMING_DWELL_S = 8.0, 12.0


def _draw(request: tuple[int, str, str, int, float, float]) -> tuple[Any, Any, float]:
    """One sweep drawn in a worker process: its truth and channels (they pickle), and the
    seconds it took."""
    seed, cause, parameter, up_steps, settle_s, dwell_s = request
    clock = time.perf_counter()
    generated = draw_sweep(seed, cause, parameter=parameter, up_steps=up_steps,
                           settle_s=settle_s, dwell_s=dwell_s)
    return generated.truth, generated.run, time.perf_counter() - clock


def explain(sweep: Sweep) -> list[str] | None:
    """EXPLANATION: the causes the sweep explanation names (``analysis.sweep.analyze``,
    merged from the shared-fit branch), or None while it is not in this tree.

    When it is, the lead adds here the explained model (the shared fit's rig with its
    named causes) and passes it to :func:`compare_diagrams` beside the baseline, so that the
    figures below gain the explained model's agreement."""
    try:
        from analysis.sweep.analyze import analyze_sweep  # type: ignore[import-not-found]
    except ImportError:
        return None
    return list(analyze_sweep(sweep).causes.named)


def _row(seed: int, truth: Any, seconds: float, measured: tuple[JudgedStep, ...],
         true: DiagramComparison, baseline: DiagramComparison,
         named: list[str] | None) -> dict[str, Any]:
    def distance(comparison: DiagramComparison) -> float:
        values = [s.distance for s in comparison.steps if math.isfinite(s.distance)]
        return float(np.median(values)) if values else math.nan

    return {
        "seed": seed,
        "cause": truth.cause,
        "moves_diagram": truth.moves_diagram,
        "parameter": truth.parameter,
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
        "named": named,
        "named_right": None if named is None else (
            named == [] if truth.cause == "none" else truth.cause in named),
        "generation_s": seconds,
    }


def _timing_sweep(template: Sweep) -> tuple[Sweep, tuple[JudgedStep, ...]]:
    """A 16-step sweep of 20 s steps over the settings of ``template``'s way up (repeated
    up and down), at its rate: records of the right length (the timing simulates them;
    nothing is compared), each step judged with a stated noise of 1 mrad."""
    up = [s for s in template.steps if s.direction == UP]
    settings = [up[round(k * (len(up) - 1) / 7)] for k in range(8)]
    fs = up[0].record.sample_rate_hz
    samples = round(TIMING_DWELL_S * fs)
    steps = []
    for number, source in enumerate(settings + settings[::-1]):
        record = Record(time_s=np.arange(samples) / fs, angle_rad=np.zeros(samples),
                        experiment="forced", rig=source.record.rig,
                        drive=source.record.drive, source=f"timing step {number}")
        steps.append(SweepStep(number, UP if number < 8 else DOWN, source.frequency_hz,
                               source.amplitude_m, TIMING_SETTLE_S, record))
    judged = tuple(JudgedStep(s.number, "undetermined", None, "", 1e-3, np.zeros((0, 8)),
                              np.zeros((0, 8))) for s in steps)
    return Sweep("timing", template.parameter, tuple(steps)), judged


def time_workers(template: Sweep, truth: Any) -> dict[str, float]:
    """Seconds to simulate (and judge) the 16-step sweep for the baseline and the true model
    with 1 worker (this process) and with 2 (a local Dask cluster, its start not counted)."""
    sweep, judged = _timing_sweep(template)
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=int, default=12)
    parser.add_argument("--up-steps", type=int, default=6, help="steps up (down: one fewer)")
    parser.add_argument("--settle", type=float, default=8.0, help="settle per step [s]")
    parser.add_argument("--dwell", type=float, default=6.0, help="dwell per step [s]")
    parser.add_argument("--jobs", type=int, default=2, help="processes drawing the sweeps")
    parser.add_argument("--no-timing", action="store_true", help="skip the worker timing")
    parser.add_argument("--json", type=Path, help="write the rows and figures here")
    parser.add_argument("--overwrite", action="store_true", help="replace the --json file")
    args = parser.parse_args(argv)
    requests = [(FIRST_SEED + k, CAUSE_CYCLE[k % len(CAUSE_CYCLE)],
                 PARAMETERS[k % len(PARAMETERS)], args.up_steps, args.settle, args.dwell)
                for k in range(args.sweeps)]
    clock = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        drawn = list(pool.map(_draw, requests))
    print(f"{len(drawn)} sweeps drawn by the reference simulator in "
          f"{time.perf_counter() - clock:.0f} s ({args.jobs} processes)")
    rows = []
    for (seed, *_), (truth, run, seconds) in zip(requests, drawn, strict=True):
        sweep = sweep_of(truth, run)
        measured = judge_measured(sweep)
        start = (truth.theta0_rad, truth.theta_dot0_rad_s)
        true, baseline = compare_diagrams([
            ("true", truth_model(truth), sweep, measured, start),
            ("baseline", truth_model(truth, with_cause=False), sweep, measured, start)])
        named = explain(sweep)  # EXPLANATION: the shared fit's named causes (None: absent)
        row = _row(seed, truth, seconds, measured, true, baseline, named)
        rows.append(row)
        print(f"seed {seed} {truth.parameter:9s} {truth.cause:22s} measured "
              f"{' '.join(row['measured'])}")
        print(f"    {true.summary()}; median distance {row['true_median_distance']:.3g}")
        print(f"    {baseline.summary()}; median distance "
              f"{row['baseline_median_distance']:.3g}"
              + ("" if named is None else f"; explanation names {named or 'nothing'}"))
    figures = _figures(rows)
    if not args.no_timing:
        template = sweep_of(drawn[0][0], drawn[0][1])
        figures["timing_16_steps_of_20_s"] = time_workers(template, drawn[0][0])
    print(to_json_text(figures))
    if args.json:
        write_json(args.json, {"made_by": "benchmarks/bench_sweeps.py", "command": sys.argv,
                               "figures": figures, "rows": rows}, overwrite=args.overwrite)
        print(f"wrote {args.json}")
    return 0


def _figures(rows: list[dict[str, Any]]) -> dict[str, Any]:
    steps = sum(r["steps"] for r in rows)
    moving = [r for r in rows if r["moves_diagram"]]
    scored = [r for r in rows if r["named_right"] is not None]
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
        "explanation": ("not in this tree (analysis.sweep.analyze)" if not scored else
                        {"scored": len(scored),
                         "named_right": sum(r["named_right"] for r in scored) / len(scored)}),
    }


if __name__ == "__main__":
    raise SystemExit(main())
