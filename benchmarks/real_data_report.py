"""Run the discrepancy analysis on the real free decays of other labs and keep the figures.

    python benchmarks/real_data_report.py [--data DIR] [--out DIR] [--figures docs/figures]

Writes one Markdown + JSON report per record into --out and copies each record's fit
figure (small PNG) into --figures for the README; prints one summary line per record.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.discrepancy import analyze_record
from analysis.record_loaders import load_record
from analysis.report import write_report
from analysis.report.discrepancy import report_json

DEFAULT_DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "real_exchange"


def main() -> int:
    """Analyse every exchange CSV in --data."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--out", type=Path, default=Path("real_data_reports"))
    parser.add_argument("--figures", type=Path, default=None)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    files = sorted(args.data.glob("*.csv"))
    if not files:
        print(f"no CSV files in {args.data}", file=sys.stderr)
        return 1
    for path in files:
        start = time.perf_counter()
        analysis = analyze_record(load_record(path), workers=args.workers)
        md = write_report(analysis, args.out, name=path.stem)
        js = report_json(analysis)
        elapsed = time.perf_counter() - start
        ranking = ", ".join(
            f"{r['cause']} {r['score']:.3g} (held-out x{r['heldout_ratio']:.3g})"
            for r in js["ranking"][:3]
        )
        print(f"{path.name}: cause {js['cause']}; baseline rms {js['baseline']['rms_residual']:.3g}"
              f" rad, extended {js['extended']['rms_residual']:.3g} rad, noise "
              f"{js['noise_rad']:.3g} rad; ranking {ranking}; {elapsed:.0f} s", flush=True)
        print(f"  localization: {js['localization']}", flush=True)
        if args.figures is not None:
            args.figures.mkdir(parents=True, exist_ok=True)
            figure = md.with_name(f"{path.stem}_fit.png")
            shutil.copy(figure, args.figures / f"real_{path.stem}.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
