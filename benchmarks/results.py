"""The benchmarks' figures as data: each run of a benchmark with ``--save`` writes its figures to
``benchmarks/results/KEY.json`` (replacing that benchmark's previous file: the earlier ones
are in git's history, and what changed and why in CHANGELOG.md), and the tables of
docs/benchmarks.md are generated from those files by ``benchmarks/page.py``.

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
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"
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
        "written_by": "benchmarks/results.py",
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
