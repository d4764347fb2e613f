"""Benchmark of the discrepancy analysis on records with a hidden cause (or none).

Decays: each case draws (seeded) the experiment and cause from every pair where the cause
can show, its size, the rig's own parameters, noise, rate and length; the virtual rig
generates the record (``harness/hidden_cause.py``).  Forced records come from the
independent reference simulator (``reference``: scipy DOP853 with events, not the
project's integrator): the paper's 2 Hz and 10 Hz settings, period-1, period-k and chaotic
motion, 10-20 s of transient discarded, noise 0.3-2 mrad, laser channel or not, every
named cause and clean records, one record alone (no decays).  The analysis sees only the
neutral CSV + JSON.

Prints, per kind, the confusion matrix and the figures against their goals: for decays
accuracy, false alarms, the gain, the true cause's parameter error and the time per case;
for forced records (issue 14) causes named, false alarms on clean records, the regime
judged right, the clean records' baseline residual over their true noise, and seconds per
60 s record at 1 kHz.

    python benchmarks/bench_discrepancy.py                        # 60 decays, 33 forced
    python benchmarks/bench_discrepancy.py --kinds forced --per-cause 1
    python benchmarks/bench_discrepancy.py --kinds free_decay,impact_decay --cases 40
    python benchmarks/bench_discrepancy.py --kinds forced --causes sensor_lag,none
    python benchmarks/bench_discrepancy.py --kinds pairs --pairs 10   # two causes at once
    python benchmarks/bench_discrepancy.py --kinds unknown --per-effect 1  # outside the registry
    python benchmarks/bench_discrepancy.py --kinds decays-pairs          # every decay pair once
    python benchmarks/bench_discrepancy.py --kinds decays-unknown --json decays.json

Effects outside the registry (``reference/unregistered.py``: two in the physics, three
in the sensor, three in the drive, and a noise decoy) must never be explained confidently by
a named cause; the analysis should flag them (``unexplained``, or the finding of the right
kind: a line, a trend, the drive frequency, the timing).

Decays from the reference simulator (``reference/decays.py``, issue 32): kind
``decays-pairs`` draws free and impact decays with two named causes at once, every pair of
its table in turn (each marked identifiable or not); kind ``decays-unknown`` draws one decay
per effect outside the registry (physics and sensor) and the noise decoys.  The figures are
the pairs named exactly, and for the effects the confident false explanations, the records
flagged (unexplained or a residual finding), the right proposed term on the physics effects
(a term outside today's library counts as missed) and the decoys' causes.  ``--json PATH``
also writes the rows and figures of the decay kinds.

``--save`` writes each group's figures to ``benchmarks/results/discrepancy-GROUP.json``
(GROUP: ``decays`` for the virtual rig's decays, ``forced``, ``pairs``, ``unknown``,
``decays-pairs``, ``decays-unknown``) for the benchmarks page (harness/results.py); a
further draw beside the first (another ``--seed``) names itself with ``--save-suffix``::

    python benchmarks/bench_discrepancy.py --kinds forced --per-cause 2 --seed 9100 \
        --save --save-suffix seed-9100      # benchmarks/results/discrepancy-forced-seed-9100.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.discrepancy import analyze_record
from analysis.experiments import FORCED
from analysis.record_loaders import load_record
from harness.hidden_cause import SHOWS_IN, draw_case, write_case
from harness.results import figure, result, save
from reference.cause_sizes import CHOICES
from reference.decays import EFFECTS as DECAY_EFFECTS
from reference.decays import PAIRS as DECAY_PAIRS
from reference.decays import Decay, draw_effect_decay, draw_pair_decay
from reference.forced_records import draw_forced_case, draw_pair, write_forced_case
from reference.regime_truth import periods_a_record_shows
from reference.unregistered import EFFECTS, draw_unregistered_case

BUDGET_S = 60.0
FORCED_GOALS = {"named": 0.9, "clean_residual_over_noise": 1.5, "seconds_per_60s": 30.0}


def main() -> int:
    """Run the batch and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", type=int, default=60, help="decay records")
    parser.add_argument("--quick", action="store_true",
                        help="one decay per (experiment, cause), one forced record per cause")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=7000)
    parser.add_argument("--kinds", default="free_decay,impact_decay,forced",
                        help="experiment kinds to draw from (comma separated)")
    parser.add_argument("--per-cause", type=int, default=3,
                        help="forced records per cause (and none)")
    parser.add_argument("--causes", default=",".join(CHOICES),
                        help="forced records: the causes to hide (comma separated)")
    parser.add_argument("--duration", type=float, default=60.0,
                        help="forced records: length [s] (at 1 kHz)")
    parser.add_argument("--pairs", type=int, default=10,
                        help="kind 'pairs': forced records with two causes at once")
    parser.add_argument("--per-effect", type=int, default=1,
                        help="kind 'unknown': forced records per effect outside the registry")
    parser.add_argument("--effects", default=",".join(EFFECTS),
                        help="kind 'unknown': the effects to add (comma separated)")
    parser.add_argument("--decay-pairs", type=int, default=len(DECAY_PAIRS),
                        help="kind 'decays-pairs': decays with two causes (default: every "
                        "pair once; more go round the pairs again)")
    parser.add_argument("--per-decay-effect", type=int, default=1,
                        help="kind 'decays-unknown': decays per effect outside the registry "
                        "(and per noise decoy)")
    parser.add_argument("--decay-effects", default=",".join(DECAY_EFFECTS),
                        help="kind 'decays-unknown': the effects (comma separated)")
    parser.add_argument("--json", type=Path, default=None,
                        help="also write the decay kinds' rows and figures to this JSON file")
    parser.add_argument("--save", action="store_true",
                        help="also write each group's figures to "
                        "benchmarks/results/discrepancy-GROUP.json (the benchmarks page)")
    parser.add_argument("--save-suffix", default="", metavar="SUFFIX",
                        help="with --save: write discrepancy-GROUP-SUFFIX.json instead, a "
                        "further draw beside the first (such as seed-9100)")
    args = parser.parse_args()
    if args.save_suffix and not args.save:
        parser.error("--save-suffix: only with --save")
    if args.save_suffix and not all(c.isalnum() or c in "-." for c in args.save_suffix):
        parser.error(f"--save-suffix: {args.save_suffix!r} is not letters, digits, '-' and '.'")
    load = os.getloadavg()[0]
    kinds = args.kinds.split(",")
    figures: dict[str, dict] = {}
    saved: dict[str, tuple[list[dict[str, str]], str]] = {}  # group -> figures, about
    if any(kind in SHOWS_IN for kind in kinds):
        saved["decays"] = run_decays(args, kinds)
    if FORCED.name in kinds:
        saved["forced"] = run_forced(args)
    if "pairs" in kinds:
        saved["pairs"] = run_pairs(args)
    if "unknown" in kinds:
        saved["unknown"] = run_unknown(args)
    if "decays-pairs" in kinds:
        figures["decays-pairs"], saved["decays-pairs"] = run_decay_pairs(args)
    if "decays-unknown" in kinds:
        figures["decays-unknown"], saved["decays-unknown"] = run_decay_unknown(args)
    if args.json is not None and figures:
        args.json.write_text(json.dumps({"command": sys.argv, "seed": args.seed, **figures},
                                        indent=2, default=float) + "\n", encoding="utf-8")
        print(f"\nfigures written to {args.json}")
    if args.save:
        suffix = f"-{args.save_suffix}" if args.save_suffix else ""
        for group, (rows, about) in saved.items():
            if rows:  # a group with no record analysed (no pair drawn) has no figures
                save(result(f"discrepancy-{group}{suffix}", rows, about=about,
                            load_at_start=load))
    return 0


def _mean_max(seconds: np.ndarray, scale: float = 1.0) -> str:
    """Seconds per record as ``mean / max``."""
    return f"{scale * seconds.mean():.1f} s / {scale * seconds.max():.1f} s"


def analyse_decay(decay: Decay, workers: int) -> tuple[dict | None, str | None, float]:
    """Write a reference decay as a lab's CSV + JSON and analyse it alone: the report (None
    on a failure, which is then described), and the seconds the analysis took."""
    with tempfile.TemporaryDirectory() as tmp:
        path = decay.write(Path(tmp), "record")
        start = time.perf_counter()
        try:
            report, error = analyze_record(load_record(path), workers=workers).as_json(), None
        except Exception as failure:  # a failure counts as a miss, with its reason shown
            reason = str(failure).replace(str(path), path.name)  # not the temporary folder
            report, error = None, f"error: {type(failure).__name__}: {reason}"[:120]
        return report, error, time.perf_counter() - start


def run_decay_pairs(args: argparse.Namespace) -> tuple[dict, tuple[list[dict[str, str]], str]]:
    """Decays from the reference simulator with two named causes at once (issue 32): both
    named and nothing else, on the identifiable pairs (the goal) and on all. The rows and
    summary, and the figures for the page with what was run."""
    plan = [DECAY_PAIRS[i % len(DECAY_PAIRS)] for i in range(args.decay_pairs)]
    print(f"{len(plan)} decays with two causes (reference simulator), {args.workers} "
          f"worker(s)", flush=True)
    rows = []
    for i, pair in enumerate(plan):
        seed = args.seed + 47 * i
        decay = draw_pair_decay(seed, pair)
        report, error, elapsed = analyse_decay(decay, args.workers)
        named, unexplained = [], False  # a failure names nothing and flags nothing
        if report is not None:
            named = [c["cause"] for c in report["causes"]]
            unexplained = bool(report.get("unexplained"))
        truth = set(pair.causes)
        found = set(named)
        verdict = "error" if error else "both" if found == truth else \
            "extra" if found - truth else f"{len(found & truth)} of 2"
        rows.append(dict(seed=seed, experiment=pair.experiment, truth=list(pair.causes),
                         identifiable=pair.identifiable, named=named, error=error,
                         unexplained=unexplained, seconds=elapsed, verdict=verdict,
                         sizes=decay.causes))
        print(f"[{i + 1}/{len(plan)}] {pair.label:52s} "
              f"{'identifiable' if pair.identifiable else 'not identifiable':16s} -> causes "
              f"{error or '+'.join(named) or 'none':40s} unexplained {unexplained!s:5s} "
              f"{elapsed:6.1f} s  {verdict}", flush=True)
    ident = [r for r in rows if r["identifiable"]]
    both_ident = sum(r["verdict"] == "both" for r in ident)
    both_all = sum(r["verdict"] == "both" for r in rows)
    one = sum(r["verdict"] == "1 of 2" for r in rows)
    extra = sum(r["verdict"] == "extra" for r in rows)
    failed = sum(r["verdict"] == "error" for r in rows)
    times = np.array([r["seconds"] for r in rows])
    print(f"\nboth causes named with nothing else: {both_ident}/{len(ident)} identifiable "
          f"pairs = {_percent(both_ident, len(ident))} (goal >= 80 %)")
    print(f"both causes named with nothing else: {both_all}/{len(rows)} all pairs = "
          f"{_percent(both_all, len(rows))}; one of the two only: {one}; a cause outside "
          f"the pair: {extra}; analysis failed: {failed}")
    print(f"seconds per record: mean {times.mean():.1f}, max {times.max():.1f}")
    free = sum(pair.experiment == "free_decay" for pair in plan)
    about = (f"{len(plan)} decays from the independent reference simulator, "
             f"`reference/decays.py`, each with two causes: {free} free, {len(plan) - free} "
             f"impact; {len(ident)} pairs marked identifiable")
    page = [figure("both causes named, nothing else, on identifiable pairs",
                   f"{both_ident}/{len(ident)} = {_percent(both_ident, len(ident))}", ">= 80 %"),
            figure("on all pairs; one of the two only; a cause outside the pair; failed",
                   f"{both_all}/{len(rows)}; {one}; {extra}; {failed}"),
            figure("time per decay (mean / max)", _mean_max(times))]
    return {"rows": rows, "summary": {
        "both_identifiable": both_ident, "identifiable": len(ident), "both_all": both_all,
        "all": len(rows), "one_only": one, "outside_pair": extra, "failed": failed,
        "seconds_mean": float(times.mean()), "seconds_max": float(times.max())}}, (page, about)


def run_decay_unknown(args: argparse.Namespace) -> tuple[dict, tuple[list[dict[str, str]], str]]:
    """Decays from the reference simulator with one effect outside the registry, and the
    noise decoys (issue 32): never a cause named with nothing flagged; flagged as
    unexplained or by a residual finding; on physics effects, the true term proposed. The
    rows and summary, and the figures for the page with what was run."""
    effects = args.decay_effects.split(",")
    unknown = set(effects) - set(DECAY_EFFECTS)
    if unknown:
        raise SystemExit(f"--decay-effects: unknown {sorted(unknown)}; expected of "
                         f"{', '.join(DECAY_EFFECTS)}")
    plan = [(e, k) for k in range(args.per_decay_effect) for e in effects]
    print(f"{len(plan)} decays with an effect outside the registry or a noise decoy "
          f"(reference simulator), {args.workers} worker(s)", flush=True)
    rows = []
    for i, (effect, _) in enumerate(plan):
        seed = args.seed + 53 * i
        spec = DECAY_EFFECTS[effect]
        decay = draw_effect_decay(seed, effect)
        report, error, elapsed = analyse_decay(decay, args.workers)
        # a failure names, flags and proposes nothing
        named, unexplained, kinds, terms, rivals = [], False, [], [], []
        if report is not None:
            named = [c["cause"] for c in report["causes"]]
            unexplained = bool(report.get("unexplained"))
            kinds = sorted({f["kind"] for f in report.get("residual_findings", [])})
            proposed = report.get("proposed_terms", [])
            terms = [f"{t['term']} ({t['region']})" for t in proposed]
            rivals = [f"{a} ({t['region']})" for t in proposed for a in t["alternatives"]]
        flagged = unexplained or bool(kinds)
        wanted = f"{spec.term} ({spec.region})"
        # right: proposed, or listed beside the proposed term as one the record cannot
        # tell from it; first: proposed itself
        first_term = spec.term is not None and wanted in terms
        right_term = first_term or (spec.term is not None and wanted in rivals)
        rows.append(dict(seed=seed, effect=effect, experiment=spec.experiment,
                         domain=spec.domain, named=named, unexplained=unexplained,
                         findings=kinds, proposed_terms=terms, alternatives=rivals,
                         flagged=flagged, error=error, first_term=first_term,
                         expected_finding=spec.finding, expected_term=spec.term,
                         term_in_library=spec.term_in_library, right_term=right_term,
                         seconds=elapsed, sizes=decay.effect_values))
        wants = f"{spec.term} ({spec.region})" if spec.term else \
            "no cause" if spec.domain == "noise" else (spec.finding or "a flag")
        print(f"[{i + 1}/{len(plan)}] {spec.experiment:12s} {effect:28s} -> causes "
              f"{error or '+'.join(named) or 'none':30s} unexplained {unexplained!s:5s} findings "
              f"{','.join(kinds) or '-':22s} terms {'; '.join(terms) or '-':30s} "
              f"{'(or ' + '; '.join(rivals) + ') ' if rivals else ''}"
              f"(wants {wants}) {elapsed:6.1f} s", flush=True)
    outside = [r for r in rows if r["domain"] != "noise"]
    decoys = [r for r in rows if r["domain"] == "noise"]
    physics = [r for r in outside if r["domain"] == "physics"]
    confident = sum(bool(r["named"]) and not r["flagged"] for r in outside)
    flagged = sum(r["flagged"] for r in outside)
    right = sum(r["right_term"] for r in physics)
    first = sum(r["first_term"] for r in physics)
    beyond = sum(not r["term_in_library"] for r in physics)
    decoy_named = [r for r in decoys if r["named"]]
    failed = sum(r["error"] is not None for r in rows)
    times = np.array([r["seconds"] for r in rows])
    print(f"\neffects outside the registry: {len(outside)} records "
          f"({len(physics)} in the physics)")
    print(f"confident false explanations (a cause named and nothing flagged): "
          f"{confident}/{len(outside)} (goal 0)")
    print(f"flagged: {flagged}/{len(outside)} = {_percent(flagged, len(outside))} "
          f"(goal >= 80 %); analysis failed (counted unflagged): {failed}")
    print(f"right proposed term on physics effects: {right}/{len(physics)} = "
          f"{_percent(right, len(physics))} (goal >= 60 %; {first} proposed first, the "
          f"rest listed as a term the record cannot tell from the one proposed); {beyond} "
          f"of them need a term outside today's library")
    print(f"decoy: causes named on {len(decoy_named)}/{len(decoys)} (goal none)"
          + "".join(f"; {r['effect']}: {'+'.join(r['named'])}" for r in decoy_named))
    print(f"seconds per record: mean {times.mean():.1f}, max {times.max():.1f}")
    sensor = len(outside) - len(physics)
    about = (f"{len(rows)} decays from `reference/decays.py`: {len(physics)} effects outside "
             f"the registry in the physics, {sensor} in the sensor, {len(decoys)} noise decoys")
    page = []
    if outside:
        page += [figure("confident false explanations (a cause named and nothing flagged)",
                        f"{confident}/{len(outside)}", "0"),
                 figure("flagged (a failed analysis counts unflagged)",
                        f"{flagged}/{len(outside)} = {_percent(flagged, len(outside))}",
                        ">= 80 %")]
    if physics:
        page.append(figure("the right proposed term on physics effects (of them proposed "
                           "first; needing a term outside the library)",
                           f"{right}/{len(physics)} ({first}; {beyond})", ">= 60 %"))
    if decoys:
        page.append(figure("causes named on the decoys", f"{len(decoy_named)}/{len(decoys)}",
                           "none"))
    page.append(figure("time per decay (mean / max)", _mean_max(times)))
    return {"rows": rows, "summary": {
        "records": len(outside), "physics": len(physics), "confident_false": confident,
        "flagged": flagged, "right_term": right, "right_term_first": first,
        "terms_outside_library": beyond,
        "decoys": len(decoys), "decoys_with_a_cause": len(decoy_named), "failed": failed,
        "seconds_mean": float(times.mean()), "seconds_max": float(times.max())}}, (page, about)


def _percent(count: int, total: int) -> str:
    return f"{100 * count / total:.0f} %" if total else "- %"


def analyse_case(case, workers: int) -> tuple[dict | None, str | None, float]:
    """Write a reference case as a lab's CSV + JSON and analyse it alone: the report (None
    on a failure, which is then described), and the seconds the analysis took."""
    with tempfile.TemporaryDirectory() as tmp:
        path = write_forced_case(case, Path(tmp))
        start = time.perf_counter()
        try:
            report, error = analyze_record(load_record(path), workers=workers).as_json(), None
        except Exception as failure:  # a failure counts as a miss, with its reason shown
            report, error = None, f"error: {type(failure).__name__}: {failure}"[:90]
        return report, error, time.perf_counter() - start


def run_unknown(args: argparse.Namespace) -> tuple[list[dict[str, str]], str]:
    """Forced records with an effect no named cause describes (issue 15): never a confident
    named cause; flagged as unexplained or by the finding of the effect's kind. The figures
    for the page, and what was run."""
    effects = args.effects.split(",")
    plan = [(e, k) for k in range(args.per_effect) for e in effects]
    print(f"{len(plan)} forced records with an effect outside the registry, "
          f"{args.duration:g} s at 1 kHz", flush=True)
    rows = []
    for i, (effect, k) in enumerate(plan):
        seed = args.seed + 43 * i
        frequency = (2.0, 10.0)[(i + k) % 2]
        case = draw_unregistered_case(seed, effect, frequency_hz=frequency,
                                      duration_s=args.duration)
        report, error, elapsed = analyse_case(case, args.workers)
        named, unexplained, kinds = [error], False, []  # a failure flags nothing
        if report is not None:
            named = [c["cause"] for c in report["causes"]]
            unexplained = bool(report.get("unexplained"))
            kinds = sorted({f["kind"] for f in report.get("residual_findings", [])})
        spec = EFFECTS[effect]
        right_kind = spec.finding is None or spec.finding in kinds
        rows.append(dict(effect=effect, domain=spec.domain, named=named,
                         unexplained=unexplained, right_kind=right_kind,
                         kind_applies=spec.finding is not None, seconds=elapsed,
                         flagged=unexplained or (spec.finding is not None and right_kind)))
        laser = "laser" if case.measurement.laser else "no laser"
        print(f"[{i + 1}/{len(plan)}] {frequency:4.0f} Hz {laser:8s} {case.regime:10s} "
              f"{effect:20s} -> causes {'+'.join(named) or 'none':28s} unexplained "
              f"{unexplained!s:5s} findings {','.join(kinds) or '-':30s} "
              f"(wants {spec.finding or 'any'}) {elapsed:6.1f} s", flush=True)
    effects_rows = [r for r in rows if r["domain"] != "noise"]
    decoys = [r for r in rows if r["domain"] == "noise"]
    confident = sum(bool(r["named"]) and not r["unexplained"] for r in effects_rows)
    any_named = sum(bool(r["named"]) for r in effects_rows)
    flagged = sum(r["flagged"] for r in effects_rows)
    flagged_unexplained = sum(r["unexplained"] for r in effects_rows)
    applies = [r for r in effects_rows if r["kind_applies"]]
    print(f"\neffects outside the registry: {len(effects_rows)} records")
    if effects_rows:
        print(f"confident false explanations (a cause named, nothing flagged): {confident} "
              f"(goal 0); a cause named at all: {any_named}")
        print(f"flagged: {flagged}/{len(effects_rows)} = "
              f"{100 * flagged / len(effects_rows):.0f} % (goal >= 80 %); of them by "
              f"unexplained: {flagged_unexplained}")
    if applies:
        print(f"the right finding kind where one applies: "
              f"{sum(r['right_kind'] for r in applies)}/{len(applies)}")
    if decoys:
        print(f"noise decoys with a cause named: {sum(bool(r['named']) for r in decoys)}/"
              f"{len(decoys)} (goal 0); outliers found: "
              f"{sum(r['right_kind'] for r in decoys)}/{len(decoys)}")
    times = np.array([r["seconds"] for r in rows])
    print(f"seconds per record: mean {times.mean():.1f}, max {times.max():.1f}")
    page = []
    if effects_rows:
        page += [figure("confident false explanations (a cause named and nothing flagged)",
                        f"{confident}/{len(effects_rows)}", "0"),
                 figure("flagged (of them as `unexplained`)",
                        f"{flagged}/{len(effects_rows)} = {_percent(flagged, len(effects_rows))}"
                        f" ({flagged_unexplained})", ">= 80 %"),
                 figure("a cause named at all", f"{any_named}/{len(effects_rows)}")]
    if applies:
        page.append(figure("the right finding kind",
                           f"{sum(r['right_kind'] for r in applies)}/{len(applies)}"))
    if decoys:
        page.append(figure("the noise decoys: a cause named; outliers found",
                           f"{sum(bool(r['named']) for r in decoys)}/{len(decoys)}; "
                           f"{sum(r['right_kind'] for r in decoys)}/{len(decoys)}", "0; all"))
    page.append(figure("time per record (mean / max)", _mean_max(times)))
    about = (f"{len(rows)} forced records of {args.duration:g} s with an effect no named "
             f"cause describes, `reference/unregistered.py`: {', '.join(effects)}")
    return page, about


def run_pairs(args: argparse.Namespace) -> tuple[list[dict[str, str]], str]:
    """Forced records from the reference simulator with two causes at once, each drawn at a
    size that shows on its own; the pair is drawn from the seed (issue 15). The figures for
    the page (none when no pair could be drawn), and what was run."""
    print(f"{args.pairs} forced records with two causes, {args.duration:g} s at 1 kHz",
          flush=True)
    rows = []
    for i in range(args.pairs):
        seed = args.seed + 41 * i
        pair = draw_pair(seed)
        frequency = (2.0, 10.0)[i % 2]
        try:
            case = draw_forced_case(seed, pair, frequency_hz=frequency, duration_s=args.duration)
        except RuntimeError as error:  # no draw of the seed shows both: not identifiable
            print(f"[{i + 1}/{args.pairs}] {' + '.join(pair)}: not drawn ({error})"[:160])
            continue
        report, error, elapsed = analyse_case(case, args.workers)
        found, apart = {error}, []
        if report is not None:
            found = {c["cause"] for c in report["causes"]}
            apart = [p["causes"] for p in report.get("indistinct", [])]
        rows.append(dict(pair=set(pair), found=found, seconds=elapsed))
        laser = "laser" if case.measurement.laser else "no laser"
        verdict = "both" if found == set(pair) else \
            "extra" if found - set(pair) else f"{len(found & set(pair))} of 2"
        print(f"[{i + 1}/{args.pairs}] {frequency:4.0f} Hz {laser:8s} {case.regime:10s} "
              f"{' + '.join(pair):45s} -> {' + '.join(sorted(found)) or 'none':45s} "
              f"{elapsed:6.1f} s  {verdict}" + (f"  (cannot tell apart: {apart})" if apart
                                                else ""), flush=True)
    about = (f"{len(rows)} forced records with two causes at once ({args.pairs} tried), the "
             f"pair drawn from the seed among all {len(CHOICES) - 1} causes, each at a size that "
             f"shows on its own; {args.duration:g} s at 1 kHz")
    if not rows:
        return [], about
    both = sum(r["found"] == r["pair"] for r in rows)
    extra = sum(bool(r["found"] - r["pair"]) for r in rows)
    one = sum(len(r["found"] & r["pair"]) == 1 and not r["found"] - r["pair"] for r in rows)
    times = np.array([r["seconds"] for r in rows])
    print(f"\nboth causes named, nothing else: {both}/{len(rows)} = "
          f"{100 * both / len(rows):.1f} % (goal >= 80 %); one of the two only: {one}; "
          f"a cause outside the pair: {extra}")
    print(f"seconds per record: mean {times.mean():.1f}, max {times.max():.1f}")
    return [figure("both causes named, nothing else",
                   f"{both}/{len(rows)} = {_percent(both, len(rows))}", ">= 80 %"),
            figure("one of the two only; a cause outside the pair", f"{one}; {extra}"),
            figure("time per record (mean / max)", _mean_max(times))], about


def run_decays(args: argparse.Namespace, kinds: list[str]) -> tuple[list[dict[str, str]], str]:
    """Decays through the virtual rig, with their figures (printed, and for the page with
    what was run)."""
    pairs = [(kind, c) for kind, causes in SHOWS_IN.items() if kind in kinds for c in causes]
    n = len(pairs) if args.quick else args.cases
    order = np.random.default_rng(args.seed).permutation(n) % len(pairs)
    rows = []
    print(f"{n} decay records, {args.workers} worker(s)", flush=True)
    for i, k in enumerate(order):
        kind, truth = pairs[int(k)]
        case = draw_case(args.seed + i, kind, truth)
        with tempfile.TemporaryDirectory() as tmp:
            path = write_case(case, Path(tmp), name="record")
            start = time.perf_counter()
            extra: list[str] = []  # causes the forward selection added after the first
            try:
                report = analyze_record(load_record(path), workers=args.workers).as_json()
                found = report["cause"]
                extra = [c["cause"] for c in report["causes"][1:]]
            except Exception as error:  # a failure counts as a miss, with its reason shown
                report, found = None, f"error: {type(error).__name__}: {error}"[:80]
            elapsed = time.perf_counter() - start
        errors = []
        if report is not None and truth != "none":
            entry = next((r for r in report["ranking"] if r["cause"] == truth), None)
            if entry is not None:
                for key, value in case.values.items():
                    fitted = entry["parameters"].get(key, {}).get("value")
                    if fitted is not None:
                        errors.append(abs(fitted / value - 1.0))
        gain = report["gain"]["rms_reduction"] if report is not None else float("nan")
        flagged = report is not None and bool(report["unexplained"])
        rows.append((kind, truth, found, elapsed, max(errors) if errors else float("nan"), gain,
                     extra, flagged))
        print(f"[{i + 1}/{n}] {kind:12s} {truth:20s} -> {found:20s} {elapsed:6.1f} s  "
              f"param err {rows[-1][4]:.3g}  rms gain {gain:.3g}"
              + (f"  + {' + '.join(extra)}" if extra else "")
              + ("  unexplained" if flagged else ""), flush=True)
    return _summary(rows), f"{n} decays with a hidden cause, or none, through the virtual rig"


def regime_right(case, report: dict) -> bool | None:
    """Periodic versus chaotic, and the period the record can show (a divisor of the true one
    whose splitting hides in the noise counts); None when the truth has not settled."""
    judged = report.get("regime") or {}
    if case.regime == "unsettled":
        return None
    shown = periods_a_record_shows(case.motion.strobe_states,
                                   case.measurement.angle_noise_rad, case.regime_truth)
    if judged.get("kind") == "periodic":
        return judged.get("period") in shown
    if case.regime == "quasi-periodic":
        return None
    return case.regime == "chaotic" and judged.get("kind") == "chaotic"


def run_forced(args: argparse.Namespace) -> tuple[list[dict[str, str]], str]:
    """Forced records from the reference simulator, with their figures (printed, and for the
    page with what was run)."""
    causes = args.causes.split(",")
    plan = [(c, k) for k in range(1 if args.quick else args.per_cause) for c in causes]
    print(f"{len(plan)} forced records of {args.duration:g} s at 1 kHz, "
          f"{args.workers} worker(s)", flush=True)
    rows = []
    for i, (truth, k) in enumerate(plan):
        seed = args.seed + 37 * i
        frequency = (2.0, 10.0)[(i + k) % 2]
        case = draw_forced_case(seed, truth, frequency_hz=frequency, duration_s=args.duration)
        report, error, elapsed = analyse_case(case, args.workers)
        found = error if report is None else \
            "+".join(sorted(c["cause"] for c in report["causes"])) or "none"
        noise = case.measurement.angle_noise_rad
        residual = report["baseline"]["rms_residual"] / noise if report else float("nan")
        right = regime_right(case, report) if report else False
        judged = (report.get("regime") or {}).get("label", "?") if report else "?"
        rows.append(dict(truth=truth, found=found, seconds=elapsed, residual=residual,
                         regime=case.regime, period=case.period, right=right,
                         frequency=frequency, laser=case.measurement.laser))
        laser = "laser" if case.measurement.laser else "no laser"
        verdict = "ok" if right else ("-" if right is None else "WRONG")
        print(f"[{i + 1}/{len(plan)}] {frequency:4.0f} Hz {laser:8s} {truth:22s} -> "
              f"{found:22s} {elapsed:6.1f} s  baseline {residual:7.3g} x noise  regime "
              f"{case.regime} judged {judged[:40]!r} {verdict}", flush=True)
    per = 1 if args.quick else args.per_cause
    drawn = f"{per} per cause" + (" and clean" if "none" in causes else "")
    if len(causes) < len(CHOICES):
        drawn = f"{per} each: {', '.join(causes)}"
    about = (f"{len(plan)} forced records of {args.duration:g} s at 1 kHz from the independent "
             f"reference simulator `reference`: {drawn}, 2 Hz and 10 Hz, laser or not, one "
             "record alone")
    return summary(rows, args.duration), about


def summary(rows: list[dict], duration_s: float) -> list[dict[str, str]]:
    """The confusion matrix and the figures against the goals, printed; the figures for the
    page."""
    page = []
    truths = sorted({r["truth"] for r in rows})
    found = sorted({r["found"] for r in rows if not r["found"].startswith("error")} | set(truths))
    print("\nconfusion matrix (rows: truth, columns: found)")
    width = max(len(c) for c in found)
    print(" " * (width + 2) + " ".join(f"{c[:6]:>6s}" for c in found))
    counts = Counter((r["truth"], r["found"]) for r in rows)
    for t in truths:
        print(f"{t:>{width}s}  " + " ".join(f"{counts[(t, f)]:6d}" for f in found))
    with_cause = [r for r in rows if r["truth"] != "none"]
    clean = [r for r in rows if r["truth"] == "none"]
    if with_cause:
        named = sum(r["truth"] == r["found"] for r in with_cause)
        goal = 100 * FORCED_GOALS["named"]
        print(f"\ncauses named: {named}/{len(with_cause)} = "
              f"{100 * named / len(with_cause):.1f} % (goal >= {goal:.0f} %)")
        page.append(figure("causes named", f"{named}/{len(with_cause)} = "
                           f"{_percent(named, len(with_cause))}", f">= {goal:.0f} %"))
    if clean:
        alarms = sum(r["found"] != "none" for r in clean)
        print(f"false alarms on clean records: {alarms}/{len(clean)} (goal 0)")
        residuals = np.array([r["residual"] for r in clean])
        print(f"clean records' baseline residual over the true noise: median "
              f"{np.nanmedian(residuals):.3g}, max {np.nanmax(residuals):.3g} "
              f"(goal <= {FORCED_GOALS['clean_residual_over_noise']:g})")
        page += [figure("false alarms", f"{alarms}/{len(clean)}", "0"),
                 figure("clean records' baseline residual / true noise (median / max)",
                        f"{np.nanmedian(residuals):.3g} / {np.nanmax(residuals):.3g}",
                        f"<= {FORCED_GOALS['clean_residual_over_noise']:g}")]
    scored = [r for r in rows if r["right"] is not None]
    right = sum(bool(r["right"]) for r in scored)
    print(f"regime judged right: {right}/{len(scored)} (goal: all); "
          f"{len(rows) - len(scored)} record(s) whose noiseless motion had not settled "
          "are not scored")
    regimes = []
    for regime in sorted({r["regime"] for r in rows}):
        sub = [r for r in rows if r["regime"] == regime]
        hit = sum(r["truth"] == r["found"] for r in sub)
        print(f"  {regime:14s} {len(sub):3d} records, cause right on {hit}")
        regimes.append(f"{len(sub)} {regime}")
    page.append(figure("regime right on scored records",
                       f"{right}/{len(scored)} ({len(rows) - len(scored)} not settled in the "
                       f"noiseless truth; {', '.join(regimes)})", "all"))
    times = np.array([r["seconds"] for r in rows])
    scale = 60.0 / duration_s
    print(f"seconds per record: mean {times.mean():.1f}, max {times.max():.1f} "
          f"({scale * times.mean():.1f} and {scale * times.max():.1f} per 60 s record; goal "
          f"<= {FORCED_GOALS['seconds_per_60s']:g})")
    page.append(figure(f"time per 60 s record on {os.cpu_count()} cores (mean / max)",
                       _mean_max(times, scale), f"<= {FORCED_GOALS['seconds_per_60s']:g} s"))
    return page


def _summary(rows) -> list[dict[str, str]]:
    """The decays' confusion matrix and figures, printed; the figures for the page."""
    truths = sorted({r[1] for r in rows})
    found = sorted({r[2] for r in rows} | set(truths))
    print("\nconfusion matrix (rows: truth, columns: found)")
    width = max(len(c) for c in found)
    print(" " * (width + 2) + " ".join(f"{c[:6]:>6s}" for c in found))
    counts = Counter((r[1], r[2]) for r in rows)
    for t in truths:
        print(f"{t:>{width}s}  " + " ".join(f"{counts[(t, f)]:6d}" for f in found))
    correct = sum(r[1] == r[2] for r in rows)
    nones = [r for r in rows if r[1] == "none"]
    alarms = sum(r[2] != "none" for r in nones)
    print(f"\naccuracy {correct}/{len(rows)} = {100 * correct / len(rows):.1f} % (goal >= 90 %)")
    page = [figure("right cause", f"{correct}/{len(rows)} = {100 * correct / len(rows):.1f} %",
                   ">= 90 %")]
    if nones:
        print(f"false alarms on none: {alarms}/{len(nones)} = {100 * alarms / len(nones):.1f} % "
              "(goal <= 5 %)")
        page.append(figure("false alarms on `none`", f"{alarms}/{len(nones)}", "<= 5 %"))
    second = sum(bool(r[6]) for r in rows)
    print(f"records given a second cause beside their one: {second}/{len(rows)}")
    right = [r for r in rows if r[1] == r[2]]
    print(f"records named right but flagged unexplained (a false flag): "
          f"{sum(r[7] for r in right)}/{len(right)}")
    page += [figure("a second cause given beside the one", f"{second}/{len(rows)}"),
             figure("named right but flagged `unexplained`",
                    f"{sum(r[7] for r in right)}/{len(right)}")]
    hits = [r for r in rows if r[1] == r[2] and r[1] != "none"]
    if hits:
        errs = np.array([r[4] for r in hits if np.isfinite(r[4])])
        gains = np.array([r[5] for r in hits])
        print(f"mean rms reduction when the cause is found: {100 * gains.mean():.1f} %")
        page.append(figure("mean rms reduction", f"{100 * gains.mean():.1f} %"))
        if errs.size:
            print(f"parameter error of the true cause: median {100 * np.median(errs):.2g} %, "
                  f"max {100 * errs.max():.2g} %, within 20 %: {np.mean(errs < 0.2) * 100:.0f} %")
            page.append(figure("true cause's parameters, error (median / max)",
                               f"{100 * np.median(errs):.2g} % / {100 * errs.max():.2g} %"))
    times = np.array([r[3] for r in rows])
    for kind in sorted({r[0] for r in rows}):
        kt = np.array([r[3] for r in rows if r[0] == kind])
        print(f"time per {kind} case: mean {kt.mean():.1f} s, max {kt.max():.1f} s")
        page.append(figure(f"time per {kind.replace('_', ' ')} (mean / max)", _mean_max(kt)))
    print(f"time per case: mean {times.mean():.1f} s = {times.mean() / BUDGET_S:.2f} x the "
          f"{BUDGET_S:.0f} s budget, max {times.max():.1f} s = {times.max() / BUDGET_S:.2f} x")
    return page


if __name__ == "__main__":
    raise SystemExit(main())
