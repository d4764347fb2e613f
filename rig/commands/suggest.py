"""``impact-rig suggest``: the forced steps that would tell a report's competing explanations
apart, written as a plan for ``impact-rig sweep --plan``."""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from analysis import quantities as q
from rig.cli import CommandError, add_command
from rig.logs import progress

if TYPE_CHECKING:
    from analysis.suggest import PairSearch, Setting
    from rig.config import RigConfig

DESCRIPTION = """\
Suggest the next experiment: the forced steps (drive frequency and amplitude) at which the
explanations an analysis left competing would predict records that differ most, against
the record's noise and beyond what their own parameter intervals can produce.

REPORT is the JSON report of a forced record ('impact-rig analyze RECORD --json
REPORT'). The competing explanations are the pairs it lists as indistinct (the record
cannot tell them apart), the cause it named against its runner-up (the best other
candidate), the best-ranked candidate against the next one when the record ranks it
within the report's BIC margin of the best, the named cause against the baseline when the
finding is weak (the report says the model still misses something, warns, or the cause's
held-out error fell by less than the policy's clear gain), and, when it names no cause,
the baseline against the best-ranked candidate (a plausible one when there is one; with
the next one too when it is within the margin); each is its fitted model, with the 95 %
intervals of its parameters, and each pair is printed with why it was chosen. A report
with none of these (no indistinct pair, no cause named, no candidate ranked) has nothing
to tell apart: that is said in one line, with exit status 2.

Every setting of the grid (--frequency-hz x --amplitude-mm) is run for each candidate
from rest, settled for --settle seconds and dwelt on for --dwell, and read as its sensor
reads (its measurement causes, no noise); the dwell's last periods are its prediction.
Two predictions' distance is the RMS difference of each drive period from the other's
nearest period, in units of the record's noise. Each candidate is also run at --draws
parameter sets drawn within its intervals; the 90th percentile of their distances from
its fitted prediction is its spread there. The separation is the distance less both
spreads: a difference the candidates' intervals cannot close. When both predictions are
periodic, a record of the dwell (at the record's sample rate) is expected to give a BIC
difference of about samples x separation^2 between them. The best --best settings of each
pair are printed and written as a plan (TOML, with what made it) that 'impact-rig sweep
--plan PLAN' runs.

Every setting is checked against the rig file's shaker limits first: a setting asked for
outside them is refused, naming it; the default grid (around the record's drive) leaves
out what the limits forbid and says so. A setting at which a simulation goes over the top
is left out and listed. Each step is predicted from rest; in the plan the steps follow one
another, so a step whose model has several attractors may settle on another one.

Where it runs: here (the default, or --workers 1), on a local Dask cluster of N worker
processes (--workers N), or on a running Dask scheduler's workers (--scheduler ADDRESS),
as 'impact-rig map' does; the figures are the same wherever it ran (the draws are seeded).
"""

EPILOG = """\
examples:
  impact-rig suggest run.report.json --out next.toml
  impact-rig suggest run.report.json --frequency-hz 6:14:9 --amplitude-mm 0.5:4:8 \\
      --dwell 30 --best 2 --workers 2 --out next.toml
  impact-rig sweep --sim --plan next.toml --out next.h5
"""

DEFAULT_DWELL_S = 20.0
DEFAULT_DRAWS = 8
DEFAULT_BEST = 3
# the default grid: around the record's drive
DEFAULT_FREQUENCIES = (0.6, 1.4, 5)  # x the record's frequency: from, to, values
DEFAULT_AMPLITUDES = (0.25, 2.0, 5)  # x the record's amplitude
SETTLE_DECAY_TIMES = 3.0  # default settle: this many 1 / (zeta omega) of the slowest model
MIN_SETTLE_S = 5.0
MAX_SETTLE_S = 60.0  # a candidate fitted with no viscous damping settles on its impacts


def grid(text: str) -> tuple[float, float, int]:
    """START:STOP:N (N values, ends included) or one VALUE."""
    parts = text.split(":")
    try:
        if len(parts) == 1:
            value = float(parts[0])
            start, stop, count = value, value, 1
        elif len(parts) == 3:
            start, stop, count = float(parts[0]), float(parts[1]), int(parts[2])
        else:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected START:STOP:N (e.g. 6:14:9) or one value") from None
    if not (math.isfinite(start) and math.isfinite(stop) and start > 0 and stop > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected values > 0")
    if count < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: N must be at least 1")
    return start, stop, count


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``suggest`` sub-command."""
    parser = add_command(
        subparsers,
        "suggest",
        "the forced steps that would tell a report's competing explanations apart -> plan",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument("report", type=Path, metavar="REPORT",
                        help="the JSON report of a forced record (impact-rig analyze --json)")
    parser.add_argument("--out", type=Path, required=True, metavar="PLAN.toml",
                        help="the plan file to write (for impact-rig sweep --plan)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace PLAN.toml if it exists")
    parser.add_argument("--config", metavar="FILE",
                        help="rig file whose shaker limits bound the search (default: the "
                        "shipped rig/default_rig.toml)")
    search = parser.add_argument_group("search")
    search.add_argument("--frequency-hz", type=grid, metavar="START:STOP:N",
                        help="drive frequencies searched (default: 0.6 to 1.4 times the "
                        "record's, 5 values)")
    search.add_argument("--amplitude-mm", type=grid, metavar="START:STOP:N",
                        help="drive amplitudes searched, mm (default: 0.25 to 2 times the "
                        "record's, 5 values)")
    search.add_argument("--settle", type=float, metavar="SECONDS",
                        help="settle time of each step (default: 3 decay times 1/(zeta "
                        "omega) of the slowest candidate, 5 to 60 s)")
    search.add_argument("--dwell", type=float, default=DEFAULT_DWELL_S, metavar="SECONDS",
                        help=f"steady-state time of each step (default {DEFAULT_DWELL_S:g})")
    search.add_argument("--draws", type=int, default=DEFAULT_DRAWS, metavar="N",
                        help="parameter sets drawn within each candidate's intervals "
                        f"(default {DEFAULT_DRAWS}; 0: the fitted values only)")
    search.add_argument("--best", type=int, default=DEFAULT_BEST, metavar="N",
                        help=f"settings kept per pair (default {DEFAULT_BEST})")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, metavar="N",
                       help="local Dask worker processes (default: run here, as with 1)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="a running Dask scheduler, e.g. tcp://127.0.0.1:8786")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Read the report, search the grid, print the best settings and write the plan."""
    from analysis.experiment_plan import ExperimentPlan, PlannedStep, write_plan
    from analysis.maps import MapRunner, SchedulerError
    from analysis.output_paths import check_outputs
    from analysis.provenance import provenance
    from analysis.suggest import ReportError, competing_pairs, report_rig, search
    from rig.commands.rig_options import load_rig_config

    for option, value, low in (("--workers", args.workers, 1), ("--draws", args.draws, 0),
                               ("--best", args.best, 1)):
        if value is not None and value < low:
            raise CommandError(f"{option} {value}: need at least {low}")
    if not (args.dwell > 0 and math.isfinite(args.dwell)):
        raise CommandError(f"--dwell {args.dwell}: expected a time > 0 s")
    if args.settle is not None and not (args.settle >= 0 and math.isfinite(args.settle)):
        raise CommandError(f"--settle {args.settle}: expected a time >= 0 s")
    check_outputs([args.out], inputs=[args.report], overwrite=args.overwrite)
    report = _read_report(args.report)
    try:
        pairs = competing_pairs(report, str(args.report))
        rig = report_rig(report, str(args.report))
    except ReportError as error:
        raise CommandError(str(error)) from None
    noise = report.get("noise_rad")
    rate = report.get("sample_rate_hz")
    if not (isinstance(noise, int | float) and noise > 0):
        raise CommandError(f"{args.report}: noise_rad {noise!r}: the differences are counted "
                           "in units of the record's noise, which must be > 0")
    if not (isinstance(rate, int | float) and rate > 0):
        raise CommandError(f"{args.report}: no sample_rate_hz (made by an older impact-rig?); "
                           "analyse the record again with 'impact-rig analyze --json'")
    config = load_rig_config(argparse.Namespace(config=args.config, sim=False))
    settle = args.settle if args.settle is not None else _default_settle(pairs)
    settings = _settings(args, report, config, settle)
    where = "here" if args.scheduler is None and (args.workers or 1) == 1 else \
        (args.scheduler or f"a local Dask cluster of {args.workers} workers")
    progress(f"{len(pairs)} pair(s) of explanations, {len(settings)} settings, "
             f"{1 + args.draws} parameter set(s) per candidate, settle {settle:g} s, dwell "
             f"{args.dwell:g} s; simulating {where} ...")
    try:
        with MapRunner(args.workers or 1, args.scheduler) as runner:
            started = time.perf_counter()  # the search, not the workers' start
            found = search(pairs, rig, settings, noise_rad=float(noise),
                           sample_rate_hz=float(rate), draws=args.draws, run_map=runner.map)
    except SchedulerError as error:
        raise CommandError(str(error)) from None
    seconds = time.perf_counter() - started
    steps: list[PlannedStep] = []
    rows: list[dict[str, Any]] = []
    for result in found:
        _print_pair(result, args.best, float(noise))
        for s in result.best(args.best):
            rows.append(_row(result, s))
            if any(p.frequency_hz == s.setting.frequency_hz
                   and p.amplitude_m == s.setting.amplitude_m for p in steps):
                continue
            steps.append(PlannedStep(s.setting.frequency_hz, s.setting.amplitude_m,
                                     s.setting.settle_s, s.setting.dwell_s, why=_why(result, s)))
    print(f"searched {len(settings)} settings in {seconds:.1f} s ({where})")
    if not steps:
        raise CommandError("no setting searched separates the explanations beyond the "
                           "spread of their own intervals; widen --frequency-hz or "
                           "--amplitude-mm, or lengthen --dwell; no plan written")
    plan = ExperimentPlan(
        tuple(steps), made_by="impact-rig suggest", source=str(args.report),
        notes=("forced steps where " + "; ".join(r.pair.label for r in found)
               + " predict records that differ most against the record's noise, beyond "
               "the spread of their intervals; each step predicted from rest"),
        extra={"search": {
            "frequencies_hz": sorted({s.frequency_hz for s in settings}),
            "amplitudes_m": sorted({s.amplitude_m for s in settings}),
            "draws": args.draws, "noise_rad": float(noise),
            "sample_rate_hz": float(rate), "ran": where, "seconds": round(seconds, 2)},
            "suggestion": rows})
    path = write_plan(args.out, plan, provenance=provenance(), inputs=[args.report],
                      overwrite=args.overwrite)
    print(f"plan: {len(steps)} step(s) -> {path} (run it: impact-rig sweep --plan {path} "
          "--out FILE.h5)")
    return 0


def _read_report(path: Path) -> dict[str, Any]:
    try:
        report = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CommandError(f"{path}: no such report") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise CommandError(f"{path}: not a JSON report ({error})") from None
    if not isinstance(report, dict):
        raise CommandError(f"{path}: not an 'impact-rig analyze --json' report")
    return report


def _default_settle(pairs: list) -> float:
    """Three decay times of the slowest candidate (its linear free decay), 5 to 60 s."""
    slowest = max(1.0 / max(c.values[q.zeta] * c.values[q.omega_rad_s], 1e-9)
                  for p in pairs for c in (p.first, p.second))
    return min(MAX_SETTLE_S, max(MIN_SETTLE_S, round(SETTLE_DECAY_TIMES * slowest, 1)))


def _settings(args: argparse.Namespace, report: dict[str, Any], config: RigConfig,
              settle: float) -> list[Setting]:
    """The grid asked for (refused, naming the setting, where the limits forbid it) or the
    default one around the record's drive (what the limits forbid left out, and said)."""
    import numpy as np

    from analysis.suggest import settings_grid
    from drivers.interfaces import LimitError
    from rig.procedures import check_drives

    drive = report.get("drive") or {}
    given = {"frequency": args.frequency_hz, "amplitude": args.amplitude_mm}
    said = drive.get("stated") or {}  # a forced report's drive: measured, and as stated
    stated = {"frequency": drive.get(q.frequency_hz, said.get(q.frequency_hz)),
              "amplitude": said.get(q.amplitude_m, drive.get(q.amplitude_m))}
    axes = {}
    for name, default, scale in (("frequency", DEFAULT_FREQUENCIES, 1.0),
                                 ("amplitude", DEFAULT_AMPLITUDES, 1e-3)):
        if given[name] is not None:
            start, stop, count = given[name]
            axes[name] = np.linspace(start, stop, count) * scale
            continue
        centre = stated[name]
        if not (isinstance(centre, int | float) and centre > 0):
            option = "--frequency-hz" if name == "frequency" else "--amplitude-mm"
            raise CommandError(f"{args.report}: the record's drive has no {name}; give "
                               f"{option} START:STOP:N")
        axes[name] = np.linspace(default[0] * centre, default[1] * centre, default[2])
    grid_ = settings_grid(axes["frequency"], axes["amplitude"], settle, args.dwell)
    allowed, refused = [], []
    for setting in grid_:
        try:
            check_drives(config.limits, config.source,
                         [(setting.frequency_hz, setting.amplitude_m)])
        except LimitError as error:
            asked = given["frequency"] is not None and given["amplitude"] is not None
            if asked or (given["frequency"] is not None and _off_axis(
                    setting.frequency_hz, config, "frequency")) or (
                    given["amplitude"] is not None and _off_axis(
                        setting.amplitude_m, config, "amplitude")):
                raise CommandError(f"setting {setting.frequency_hz:g} Hz, "
                                   f"{setting.amplitude_m * 1e3:g} mm: {error}") from None
            refused.append(setting)
            continue
        allowed.append(setting)
    if refused:
        print(f"left out {len(refused)} setting(s) of the default grid that the shaker limits "
              f"of {config.source} forbid: " + ", ".join(
                  f"{s.frequency_hz:.4g} Hz {s.amplitude_m * 1e3:.4g} mm" for s in refused))
    if not allowed:
        raise CommandError(f"no setting of the grid lies within the shaker limits of "
                           f"{config.source}")
    return allowed


def _off_axis(value: float, config: RigConfig, name: str) -> bool:
    """True when a value given on this axis lies outside its own limit."""
    limits = config.limits
    if name == "frequency":
        return not limits.min_frequency_hz <= value <= limits.max_frequency_hz
    return value > limits.max_amplitude_m


def _print_pair(result: PairSearch, best: int, noise: float) -> None:
    pair = result.pair
    print(f"{pair.label}: {pair.why}")
    kept = result.best(best)
    if not kept:
        print("  no setting separates them beyond the spread of their intervals")
    for rank, s in enumerate(kept, start=1):
        r = s.result
        bic = s.expected_bic_difference
        print(f"  {rank}. {s.setting.frequency_hz:.4g} Hz, {s.setting.amplitude_m * 1e3:.4g} mm:"
              f" separation {r.separation:.3g} x noise (distance {r.distance:.3g}, spreads "
              f"{r.spread_first:.3g} and {r.spread_second:.3g}); {pair.first.name} "
              f"{r.regime_first}, {pair.second.name} {r.regime_second}"
              + (f"; expected BIC difference {bic:.3g} over a {s.setting.dwell_s:g} s dwell"
                 if bic is not None else "; compared as clouds (not both periodic)"))
    stopped = [s for s in result.ranked if s.result.stopped]
    for s in stopped:
        print(f"  left out {s.setting.frequency_hz:.4g} Hz, {s.setting.amplitude_m * 1e3:.4g} "
              f"mm: {s.result.stopped}")


def _why(result: PairSearch, s: Any) -> str:
    r = s.result
    return (f"{result.pair.label}: separation {r.separation:.3g} x noise; predicted "
            f"{result.pair.first.name} {r.regime_first}, {result.pair.second.name} "
            f"{r.regime_second}")


def _row(result: PairSearch, s: Any) -> dict[str, Any]:
    r = s.result
    row = {"pair": [result.pair.first.name, result.pair.second.name],
           q.frequency_hz: s.setting.frequency_hz, q.amplitude_m: s.setting.amplitude_m,
           "separation_in_noise": r.separation, "distance_in_noise": r.distance,
           "spread_in_noise": [r.spread_first, r.spread_second],
           "regimes": [r.regime_first, r.regime_second], "dwell_samples": s.samples}
    if s.expected_bic_difference is not None:
        row["expected_bic_difference"] = s.expected_bic_difference
    return row
