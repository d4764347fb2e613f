"""Generate the tables of docs/benchmarks.md from the benchmarks' results (benchmarks/results/,
written by ``--save``: benchmarks/results.py).

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
import re
import sys
from pathlib import Path
from typing import Any

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.results import RESULTS, ROOT, load_results

PAGE = ROOT / "docs" / "benchmarks.md"
START = re.compile(r"^<!-- benchmarks: (?P<keys>[\w .-]+?) -->$")
END = "<!-- end of generated table -->"
HEADER = ["| what to run | figure | now | goal | measured |", "|---|---|---|---|---|"]


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _measured(outcome: dict[str, Any]) -> str:
    """When, under which load and at which commit a saved run measured its figures."""
    commit = outcome["commit"] or "no git"
    return f"{outcome['date']}, load {outcome['load']}, {commit[:10]}{commit[40:]}"


def table(results: dict[str, dict[str, Any]], keys: list[str]) -> list[str]:
    """The Markdown table of these benchmarks: one row per figure, the command on the first."""
    rows = list(HEADER)
    for key in keys:
        outcome = results[key]
        run = f"`{outcome['command']}`" + (f" ({outcome['about']})" if outcome["about"] else "")
        for at, shown in enumerate(outcome["figures"]):
            measured = shown.get("measured") or _measured(outcome)
            cells = [run if at == 0 else "", shown["figure"], shown["now"], shown["goal"], measured]
            rows.append("|" + "|".join(f" {_cell(cell)} " if cell else " " for cell in cells) + "|")
    return rows


def generated(page: str, results: dict[str, dict[str, Any]]) -> str:
    """The page with every marked table generated again from ``results``."""
    lines, out, placed = page.splitlines(), [], []
    at = 0
    while at < len(lines):
        out.append(lines[at])
        marker = START.match(lines[at])
        at += 1
        if marker is None:
            continue
        keys = marker["keys"].split()
        missing = [key for key in keys if key not in results]
        if missing:
            raise ValueError(f"{PAGE.name}: no result for {missing} (benchmarks/results/KEY.json)")
        out += table(results, keys)
        placed += keys
        while at < len(lines) and lines[at] != END:
            at += 1
        if at == len(lines):
            raise ValueError(f"{PAGE.name}: no '{END}' after the table of {keys}")
        out.append(END)
        at += 1
    left_out = sorted(set(results) - set(placed))
    if left_out:
        raise ValueError(f"{PAGE.name}: the results {left_out} are in no table (add their keys "
                         "to a '<!-- benchmarks: ... -->' marker)")
    return "\n".join(out) + "\n"


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
