"""Benchmark of the loop that tells competing explanations apart (issue 37): a forced record
that leaves its cause undecided, ``impact-rig suggest`` on its report, the suggested step
recorded, and both records analysed together.

Each case draws (seeded) a forced record from the independent reference simulator
(``reference/forced_records.py``: scipy DOP853 with events, never the project's
integrator): a rig with one hidden cause, drawn at 10 Hz and sized to show in a record
at the drawn drive (``draw_forced_case``), then recorded for ``--first-duration`` (10 s)
from rest at a weaker drive, ``--first-amplitude`` (0.6) times the drawn amplitude
(``reference/next_step.py``), where the causes of ``--causes`` look alike: a sensor's
cubic nonlinearity, small on a small swing on one side of the barrier, reads much as a
zero offset does; a softer contact law, on gentler impacts, much as a barrier placed
elsewhere does (the forced-pairs benchmark named a contact exponent as a barrier offset).
The first record is analysed alone (``impact-rig analyze --json``); the case is decided
already when its report names the true cause and lists it in no ``indistinct`` pair.
Such first records are the rule: the six cases drawn while this benchmark was
written (10 s and 20 s records, at the drawn drive and at 0.4 of it, a sensor
nonlinearity, a sensor offset and a contact exponent) were all decided.  So every case
runs the loop, and the figures are given over the undecided ones and over all (with
``--only-undecided`` only the undecided run it, ``--cases`` of them):

1. ``impact-rig suggest REPORT --best 1 --workers 2`` (its default grid around the
   record's drive, its default settle, dwell and draws; the search on a local Dask cluster
   of 2 processes, as on 2 cores), timed;
2. each step of the plan recorded on the same drawn rig, with the same hidden cause at the
   same size, by the reference simulator (``reference/next_step.py``: from rest, drive
   phase 0 at the step's start, the settle discarded) and written as a lab's CSV and JSON;
3. ``impact-rig analyze FIRST.csv STEP.csv ...``: the records given together are analysed
   as one sweep of one rig (its causes shared by every record).

It prints how often the true cause is named before the loop (the first report's cause)
and after it (the joint analysis names exactly the true cause), against the goal of 80 %
after on the undecided cases; and the seconds of one suggestion (the whole ``suggest``
command, on this machine's 2 cores, with its load).

    python benchmarks/bench_suggest.py                      # 6 cases, each through the loop
    python benchmarks/bench_suggest.py --cases 1 --max-draws 1      # one loop, a smoke run
    python benchmarks/bench_suggest.py --only-undecided --cases 4 --max-draws 40
    python benchmarks/bench_suggest.py --causes sensor_nonlinearity,sensor_offset --first-duration 5
    python benchmarks/bench_suggest.py --save   # also benchmarks/results/suggest.json (the page)

Runs over other seeds, made in parallel with ``--json``, are counted together with
``--rows-from`` (their rows taken as they are, this run's cases added after them; the
figures and the saved page name every run's command):

    python benchmarks/bench_suggest.py --max-draws 0 --rows-from a.json --rows-from b.json --save
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys
import tempfile
import time
import tomllib
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.json_output import to_json_text, write_json
from harness.results import figure, result, save
from reference.forced_records import FREQUENCIES_HZ, draw_forced_case, write_forced_case
from reference.next_step import at_setting
from rig.cli import main as impact_rig

FIRST_SEED = 3700
DEFAULT_CAUSES = ("sensor_nonlinearity", "contact_exponent")
GOAL_AFTER = 0.8  # the bar: the true cause named after the loop
FIRST_STEP = 99  # the noise of a first record driven weaker than drawn (next_step's step)


def decided(report: dict[str, Any], truth: str) -> bool:
    """Whether a record's report already decides: it names the true cause, and lists it in
    no pair it cannot tell apart."""
    pairs = [set(p["causes"]) for p in report.get("indistinct") or []]
    return report.get("cause") == truth and not any(truth in p for p in pairs)


def run_command(words: list[str]) -> tuple[int, str, float]:
    """``impact-rig WORDS`` in this process: its exit status, what it printed (stdout and
    stderr) and the seconds it took."""
    out = io.StringIO()
    clock = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        status = impact_rig(words)
    return status, out.getvalue(), time.perf_counter() - clock


def run_case(seed: int, cause: str, args: argparse.Namespace, folder: Path
             ) -> dict[str, Any]:
    """One case: its first record analysed, and the loop when that leaves it undecided."""
    drawn = draw_forced_case(seed, cause, frequency_hz=args.frequency,
                             duration_s=args.first_duration)
    case = drawn
    if args.first_amplitude != 1.0:  # the same rig and cause, driven where they look alike
        case = at_setting(drawn, drawn.drive.stated_frequency_hz,
                          round(args.first_amplitude * drawn.drive.stated_amplitude_m, 5),
                          drawn.transient_s, args.first_duration, step=FIRST_STEP)
    first = write_forced_case(case, folder, "first")
    report_path = folder / "first.report.json"
    status, printed, seconds = run_command(
        ["analyze", str(first), "--json", str(report_path), "--quiet",
         "--workers", str(args.workers)])
    row: dict[str, Any] = {
        "seed": seed, "cause": cause, "frequency_hz": case.drive.stated_frequency_hz,
        "amplitude_m": case.drive.stated_amplitude_m, "regime": case.regime,
        "noise_rad": case.measurement.angle_noise_rad, "laser": case.measurement.laser,
        "causes": case.causes, "first_analysis_s": seconds}
    if status != 0:
        return row | {"failed": f"first analysis: {printed.strip().splitlines()[-1:]}"}
    report = json.loads(report_path.read_text(encoding="utf-8"))
    row |= {"before": report.get("cause"),
            "indistinct": [p["causes"] for p in report.get("indistinct") or []],
            "decided_at_first": decided(report, cause)}
    if row["decided_at_first"] and args.only_undecided:
        return row
    plan_path = folder / "next.toml"
    status, printed, seconds = run_command(
        ["suggest", str(report_path), "--best", "1", "--out", str(plan_path), "--quiet",
         "--workers", str(args.workers)])
    row["suggest_s"] = seconds
    row["suggest_printed"] = printed
    if status != 0 and "no competing explanations" in printed:
        # nothing indistinct, nothing named and no candidate ranked to set against the
        # baseline: the case stays as the first record left it
        return row | {"nothing_to_suggest": printed.strip().splitlines()[-1]}
    if status != 0:
        return row | {"failed": f"suggest: {printed.strip().splitlines()[-1:]}"}
    plan = tomllib.loads(plan_path.read_text(encoding="utf-8"))
    files, steps = [first], []
    for number, step in enumerate(plan["step"], start=1):
        further = at_setting(case, step["frequency_hz"], step["amplitude_m"],
                             step["settle_s"], step["dwell_s"], step=number)
        files.append(write_forced_case(further, folder, f"step{number}"))
        steps.append({key: step[key] for key in ("frequency_hz", "amplitude_m", "settle_s",
                                                  "dwell_s")} | {"regime": further.regime,
                                                                 "why": step.get("why", "")})
    row["steps"] = steps
    joint_path = folder / "joint.report.json"
    status, printed, seconds = run_command(
        ["analyze", *map(str, files), "--json", str(joint_path), "--quiet",
         "--workers", str(args.workers)])
    row["joint_analysis_s"] = seconds
    if status != 0:
        return row | {"failed": f"joint analysis: {printed.strip().splitlines()[-1:]}"}
    joint = json.loads(joint_path.read_text(encoding="utf-8"))
    row["after"] = list(joint["sweep"]["causes"]["named"])
    return row


def figures(rows: list[dict[str, Any]], drawn: int) -> dict[str, Any]:
    """The loop's figures over the rows (see the module's docstring): over the cases the
    first record left undecided, and over every case that ran the loop."""
    looped = [r for r in rows if "before" in r and ("suggest_s" in r
                                                    or "nothing_to_suggest" in r)]
    undecided = [r for r in looped if not r["decided_at_first"]]
    # the searches run: a report with nothing to tell apart is refused before any
    times = [r["suggest_s"] for r in looped if "suggest_s" in r
             and "nothing_to_suggest" not in r]
    return {
        "drawn": drawn,
        "decided_at_first": sum(bool(r.get("decided_at_first")) for r in rows),
        "loop_cases": len(looped),
        "loops_completed": sum("after" in r for r in looped),
        "failed": sum("failed" in r for r in rows),
        "nothing_to_suggest": sum("nothing_to_suggest" in r for r in rows),
        "undecided": _named(undecided),
        "every_loop": _named(looped),
        "suggest_s": {"mean": sum(times) / len(times), "max": max(times)} if times else None,
        "goal_after": GOAL_AFTER,
        "met": bool(undecided) and _named(undecided)["after"] >= GOAL_AFTER,
    }


def _named(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """How often the true cause is named before the loop (the first record's report) and
    after it (the joint analysis names exactly it; and among others)."""
    count = len(rows)
    return {
        "cases": count,
        "before": sum(r["before"] == r["cause"] for r in rows) / count if count else None,
        "after": sum(r.get("after") == [r["cause"]] for r in rows) / count if count else None,
        "after_among_others": sum(r["cause"] in (r.get("after") or []) for r in rows),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=6, help="cases that run the loop")
    parser.add_argument("--max-draws", type=int, default=24,
                        help="cases drawn at most (those decided at first included)")
    parser.add_argument("--seed", type=int, default=FIRST_SEED, help="the first case's seed")
    parser.add_argument("--causes", default=",".join(DEFAULT_CAUSES),
                        help="the causes hidden in turn (comma separated)")
    parser.add_argument("--frequency", type=float, default=10.0, choices=FREQUENCIES_HZ,
                        help="the first record's drive frequency [Hz]")
    parser.add_argument("--first-duration", type=float, default=10.0,
                        help="the first record's length [s] (at 1 kHz)")
    parser.add_argument("--first-amplitude", type=float, default=0.6,
                        help="the first record's drive amplitude, as a fraction of the one "
                        "drawn with the case (its cause sized to show there)")
    parser.add_argument("--only-undecided", action="store_true",
                        help="run the loop only on the cases the first record leaves "
                        "undecided (--cases of them); without it every case runs it")
    parser.add_argument("--workers", type=int, default=2,
                        help="analyze --workers and suggest --workers (2: a local Dask "
                        "cluster of 2 processes for the search)")
    parser.add_argument("--keep", type=Path, help="keep every case's files in this folder")
    parser.add_argument("--json", type=Path, help="write the rows and figures here")
    parser.add_argument("--overwrite", action="store_true", help="replace the --json file")
    parser.add_argument("--rows-from", type=Path, action="append", default=[],
                        metavar="JSON", help="count the cases of an earlier run's --json "
                        "file too (repeatable; runs over other seeds made in parallel)")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/suggest.json")
    args = parser.parse_args(argv)
    if args.json and args.json.exists() and not args.overwrite:
        parser.error(f"{args.json}: exists; pass --overwrite to replace it")
    causes = args.causes.split(",")
    load = os.getloadavg()[0]
    clock = time.perf_counter()
    rows: list[dict[str, Any]] = []
    earlier: list[str] = []
    for path in args.rows_from:
        try:
            made = json.loads(path.read_text(encoding="utf-8"))
            rows += made["rows"]
            earlier.append(" ".join(["python", "benchmarks/bench_suggest.py",
                                     *made["command"][1:]]))
        except (OSError, ValueError, KeyError, TypeError) as error:
            parser.error(f"--rows-from {path}: not a --json file of this benchmark ({error})")
    args.earlier = earlier
    before = len(rows)
    drawn = 0
    while drawn < args.max_draws and sum(
            not r.get("decided_at_first", True) or not args.only_undecided for r in rows
    ) < args.cases:
        seed, cause = args.seed + drawn, causes[drawn % len(causes)]
        drawn += 1
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            if args.keep:
                folder = args.keep / f"case-{seed}"
                folder.mkdir(parents=True, exist_ok=False)
            try:
                row = run_case(seed, cause, args, folder)
            except Exception as error:  # a failure is a figure, not the end of the run
                row = {"seed": seed, "cause": cause,
                       "failed": f"{type(error).__name__}: {error}"}
        rows.append(row)
        _print_row(row)
        _write(args, figures(rows, before + drawn), rows)
    found = figures(rows, before + drawn)
    print(f"{drawn} cases drawn and run ({before} more from --rows-from) in "
          f"{time.perf_counter() - clock:.0f} s "
          f"(load {load:.1f} at the start, {os.getloadavg()[0]:.1f} at the end)")
    print(to_json_text(found))
    _write(args, found, rows)
    if args.save:
        _save(args, found, load)
    return 0


def _print_row(row: dict[str, Any]) -> None:
    head = f"seed {row['seed']} {row['cause']:20s}"
    if "failed" in row and "before" not in row:
        print(f"{head} FAILED: {row['failed']}", flush=True)
        return
    first = (f"{head} {row['frequency_hz']:g} Hz {row['amplitude_m'] * 1e3:.3g} mm "
             f"{row['regime']:10s} first record names {row['before']}"
             + (f", indistinct {row['indistinct']}" if row["indistinct"] else ""))
    if row["decided_at_first"] and "suggest_s" not in row:
        print(f"{first}: decided, no loop", flush=True)
        return
    steps = "; ".join(f"{s['frequency_hz']:.4g} Hz {s['amplitude_m'] * 1e3:.3g} mm "
                      f"({s['regime']})" for s in row.get("steps", []))
    if "nothing_to_suggest" in row:
        print(f"{first}\n    suggest: {row['nothing_to_suggest']}", flush=True)
        return
    print(f"{first}\n    suggest {row.get('suggest_s', float('nan')):.1f} s -> {steps or '-'}"
          f"\n    together: {row.get('after', row.get('failed'))}", flush=True)


def _write(args: argparse.Namespace, found: dict[str, Any], rows: list[dict[str, Any]]) -> None:
    if args.json:
        write_json(args.json, {"made_by": "benchmarks/bench_suggest.py", "command": sys.argv,
                               "figures": found, "rows": rows}, overwrite=True)


def _save(args: argparse.Namespace, found: dict[str, Any], load: float) -> None:
    """The figures as rows of the benchmarks page (harness/results.py)."""
    undecided, every = found["undecided"], found["every_loop"]
    rows = [
        figure("cases drawn / decided by the first record alone / run through the loop",
               f"{found['drawn']} / {found['decided_at_first']} / {found['loop_cases']}"),
        figure("true cause named, cases the first record left undecided: before / after "
               "the loop", f"{_share(undecided['before'], undecided['cases'])} / "
               f"{_share(undecided['after'], undecided['cases'])}",
               f">= {100 * GOAL_AFTER:.0f} % after"),
        figure("true cause named, every case through the loop: before / after",
               f"{_share(every['before'], every['cases'])} / "
               f"{_share(every['after'], every['cases'])}"),
        figure("loop cases whose report had nothing for suggest (none indistinct, no cause "
               "named, no candidate ranked)",
               f"{found['nothing_to_suggest']}/{found['loop_cases']}"),
        figure("loops failed", f"{found['failed']}/{found['drawn']}", "0"),
    ]
    if found["suggest_s"] is not None:
        rows.append(figure("one suggestion (the whole command, default grid: 5 x 5 settings, "
                           f"8 draws, --workers {args.workers}), on 2 cores (mean / max)",
                           f"{found['suggest_s']['mean']:.0f} s / "
                           f"{found['suggest_s']['max']:.0f} s"))
    about = (f"first records of {args.first_duration:g} s at {args.frequency:g} Hz, "
             f"{args.first_amplitude:g} x the drawn amplitude, from the "
             "independent reference simulator, hiding in turn " + ", ".join(
                 args.causes.split(",")) + "; the suggested steps recorded by "
             "`reference/next_step.py`")
    if args.earlier:
        about += "; counted with the cases of " + "; ".join(f"`{c}`" for c in args.earlier)
    save(result("suggest", rows, about=about, load_at_start=load))


def _share(share: float | None, count: int) -> str:
    return "-" if share is None else f"{round(share * count)}/{count} = {100 * share:.0f} %"


if __name__ == "__main__":
    raise SystemExit(main())
