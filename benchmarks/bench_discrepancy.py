"""Benchmark of the discrepancy analysis on randomized records with a hidden cause.

Each case draws (seeded) the experiment and cause from every pair where the cause
can show, its size, the rig's own parameters, noise, rate and length; the virtual
rig generates the record, the analysis sees only the neutral CSV + JSON.  Prints
the confusion matrix, accuracy, false alarms on `none`, the gain, the error of the
true cause's parameters and the time per case against the 60 s budget.

    python benchmarks/bench_discrepancy.py            # 60 cases
    python benchmarks/bench_discrepancy.py --quick    # one case per (experiment, cause)
    python benchmarks/bench_discrepancy.py --cases 120 --workers 2
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.discrepancy import analyze_record
from analysis.discrepancy.analyze import priors_from_decays
from analysis.records import load_record
from tests.discrepancy.hidden_cause import (
    SHOWS_IN,
    draw_case,
    write_case,
    write_companion_decay,
)

BUDGET_S = 60.0


def main() -> int:
    """Run the batch and print the figures."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", type=int, default=60)
    parser.add_argument("--quick", action="store_true", help="one case per (experiment, cause)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=7000)
    parser.add_argument("--kinds", default="free_decay,impact_decay,forced",
                        help="experiment kinds to draw from (comma separated)")
    args = parser.parse_args()
    kinds = args.kinds.split(",")
    pairs = [(kind, c) for kind, causes in SHOWS_IN.items() if kind in kinds for c in causes]
    n = len(pairs) if args.quick else args.cases
    order = np.random.default_rng(args.seed).permutation(n) % len(pairs)
    rows = []
    print(f"{n} cases, {args.workers} worker(s)", flush=True)
    for i, k in enumerate(order):
        kind, truth = pairs[int(k)]
        case = draw_case(args.seed + i, kind, truth)
        with tempfile.TemporaryDirectory() as tmp:
            path = write_case(case, Path(tmp), name="record")
            companion = write_companion_decay(case, Path(tmp)) if kind == "forced" else None
            start = time.perf_counter()
            try:
                # a forced run comes with the rig's impact decay, which starts the model values
                priors = priors_from_decays(impact_decay=load_record(companion)) \
                    if companion is not None else None
                report = analyze_record(
                    load_record(path), workers=args.workers, priors=priors
                ).as_json()
                found = report["cause"]
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
        rows.append((kind, truth, found, elapsed, max(errors) if errors else float("nan"), gain))
        print(f"[{i + 1}/{n}] {kind:12s} {truth:20s} -> {found:20s} {elapsed:6.1f} s  "
              f"param err {rows[-1][4]:.3g}  rms gain {gain:.3g}", flush=True)
    _summary(rows)
    return 0


def _summary(rows) -> None:
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
    if nones:
        print(f"false alarms on none: {alarms}/{len(nones)} = {100 * alarms / len(nones):.1f} % "
              "(goal <= 5 %)")
    hits = [r for r in rows if r[1] == r[2] and r[1] != "none"]
    if hits:
        errs = np.array([r[4] for r in hits if np.isfinite(r[4])])
        gains = np.array([r[5] for r in hits])
        print(f"mean rms reduction when the cause is found: {100 * gains.mean():.1f} %")
        if errs.size:
            print(f"parameter error of the true cause: median {100 * np.median(errs):.2g} %, "
                  f"max {100 * errs.max():.2g} %, within 20 %: {np.mean(errs < 0.2) * 100:.0f} %")
    times = np.array([r[3] for r in rows])
    for kind in sorted({r[0] for r in rows}):
        kt = np.array([r[3] for r in rows if r[0] == kind])
        print(f"time per {kind} case: mean {kt.mean():.1f} s, max {kt.max():.1f} s")
    print(f"time per case: mean {times.mean():.1f} s = {times.mean() / BUDGET_S:.2f} x the "
          f"{BUDGET_S:.0f} s budget, max {times.max():.1f} s = {times.max() / BUDGET_S:.2f} x")


if __name__ == "__main__":
    raise SystemExit(main())
