"""The benchmarks' figures as data: each run of a benchmark with ``--save`` writes its figures to
``benchmarks/results/KEY.json`` (replacing that benchmark's previous file: the earlier ones
are in git's history, and what changed and why in CHANGELOG.md), and the tables of
docs/benchmarks.md are generated from those files (:func:`generated`, run by
``python benchmarks/page.py``).

A file holds what made it (the command, the UTC date, the git commit, the machine and its
load) and the figures, one per row: what is measured, the figure now, the goal (``-`` when
none). A figure measured in another run than the file's (the files made from the page's
tables before the benchmarks wrote JSON) carries its own ``measured``.
"""

from __future__ import annotations

import datetime
import json
import os
import platform
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
FORMAT = 1


def figure(what: str, now: str, goal: str = "-") -> dict[str, str]:
    """One row of a benchmark's table: what is measured, the figure now, its goal."""
    return {"figure": what, "now": now, "goal": goal}


def _commit() -> str | None:
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain",
                                "--untracked-files=no"], capture_output=True, text=True,
                               timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return head + (" with local changes" if dirty else "")


def result(key: str, figures: list[dict[str, str]], *, about: str = "",
           load_at_start: float | None = None) -> dict[str, Any]:
    """A benchmark's result: its figures with what made them. ``load_at_start`` is the
    one-minute load average when the run began (``os.getloadavg()[0]``); the load at the end
    is read here."""
    load_now = os.getloadavg()[0]
    loads = [load_now] if load_at_start is None else [load_at_start, load_now]
    return {
        "format": FORMAT,
        "benchmark": key,
        "command": " ".join(["python", *_relative_argv()]),
        "about": about,
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
        "commit": _commit(),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.system()} "
                   f"{platform.release()}, Python {platform.python_version()}",
        "load": "-".join(f"{value:.1f}" for value in sorted(set(loads))),
        "figures": figures,
        "written_by": "harness/results.py",
    }


def _relative_argv() -> list[str]:
    script = Path(sys.argv[0]).resolve()
    shown = script.relative_to(ROOT) if script.is_relative_to(ROOT) else script
    return [str(shown), *(word for word in sys.argv[1:] if word != "--save")]


def save(outcome: dict[str, Any], folder: Path = RESULTS) -> Path:
    """Write a result as ``folder/KEY.json`` and say where; the page is regenerated with
    ``python benchmarks/page.py``."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{outcome['benchmark']}.json"
    path.write_text(json.dumps(outcome, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    print(f"figures written to {path}; regenerate the page: python benchmarks/page.py")
    return path


def load_results(folder: Path = RESULTS) -> dict[str, dict[str, Any]]:
    """Every saved result by its key."""
    found = {}
    for path in sorted(folder.glob("*.json")):
        outcome = json.loads(path.read_text(encoding="utf-8"))
        if outcome.get("format") != FORMAT or outcome.get("benchmark") != path.stem:
            raise ValueError(f"{path}: not a benchmark result of format {FORMAT} named {path.stem}")
        found[path.stem] = outcome
    return found


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
