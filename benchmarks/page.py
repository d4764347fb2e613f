"""Generate the tables of docs/benchmarks.md from the benchmarks' results (benchmarks/results/,
written by ``--save``; the format and the tables: harness/results.py).

The page says where each table goes and which benchmarks it holds, in order, by a marker
line; the lines up to the end marker are the generated table::

    <!-- benchmarks: simulate daq-stream -->
    | what to run | figure | now | goal | measured |
    ...
    <!-- end of generated table -->

Every result must be on the page, and every key on the page must have a result.

    python benchmarks/page.py            # rewrite the page's tables from the results
    python benchmarks/page.py --check    # exit 1, saying which table differs, if out of date
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from harness.results import PAGE, RESULTS, ROOT, generated, load_results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="change nothing; exit 1 if the page is not what the results make")
    args = parser.parse_args(argv)
    try:
        page = PAGE.read_text(encoding="utf-8")
        fresh = generated(page, load_results(RESULTS))
    except ValueError as error:
        print(f"benchmarks/page.py: {error}", file=sys.stderr)
        return 2
    if fresh == page:
        print(f"{PAGE.relative_to(ROOT)} is up to date with {RESULTS.relative_to(ROOT)}/")
        return 0
    if args.check:
        print(f"{PAGE.relative_to(ROOT)} is out of date: run python benchmarks/page.py",
              file=sys.stderr)
        return 1
    PAGE.write_text(fresh, encoding="utf-8")
    print(f"{PAGE.relative_to(ROOT)} written from {RESULTS.relative_to(ROOT)}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
