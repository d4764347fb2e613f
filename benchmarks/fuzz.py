"""Generated input at the program's boundaries for as long as asked: bad answers found.

The same checks and strategies as the suite's ``tests/fuzz`` (``harness.fuzz.boundaries``,
``harness.fuzz.modbus``, ``harness.fuzz.command_line``): the DAQ frame decoder, the exchange
CSV and sidecar, the rig file, damaged recordings, the shaker driver against an amplifier
whose replies are mangled, the amplifier emulator's Modbus server against hostile
requests (both real pymodbus over loopback TCP; the driver reconnecting or not), and every
``impact-rig`` sub-command's arguments.  Each answer must be a correct result or one line
naming what was wrong, within 5 s; a command line accepted and still at work after 5 s (an
analysis, a recording) is killed and counted as working, not judged.
Hypothesis runs in rounds of ``--round`` examples with fresh random seeds until the
time is up; a failure is shrunk, counted by its kind (exception type and first words),
and the run goes on.

Printed per boundary: inputs tried, distinct failures (with one example each), the
slowest answer; the figures also as one JSON line at the end (``--json FILE`` writes it).
``--save`` writes the table's rows: the file boundaries to benchmarks/results/fuzz.json,
the amplifier's and the command lines' to benchmarks/results/fuzz-hardware-and-cli.json
(each file only when one of its boundaries ran).

    python benchmarks/fuzz.py --minutes 10                      (every boundary, 10 min each)
    python benchmarks/fuzz.py --minutes 1 --boundary exchange --boundary cli
    python benchmarks/fuzz.py --minutes 1 --save
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.errors import HypothesisException

from harness.fuzz import boundaries as b
from harness.fuzz import command_line, modbus
from harness.results import figure, result, save

BOUNDARIES = (
    "frames", "exchange", "rig_file", "recording", "modbus_driver", "modbus_server", "cli"
)
# the benchmarks page's rows: a results key, how its figure starts, its boundaries in order
SAVED = (
    ("fuzz", "generated input per boundary ({}): ", {
        "frames": "DAQ frames", "exchange": "exchange CSV + sidecar", "rig_file": "rig file",
        "recording": "damaged recording"}),
    ("fuzz-hardware-and-cli", "generated {}: ", {
        "cli": "command lines for every sub-command",
        "modbus_driver": "the shaker driver against mangled amplifier replies",
        "modbus_server": "hostile requests to the amplifier emulator"}),
)
GOAL = "0 bad answers, every answer within 5 s, over 10 min per boundary"


class Boundary:
    """One boundary: how to run one generated input, and what was seen."""

    def __init__(self, name: str, strategy, check: Callable[..., None]) -> None:
        self.name = name
        self.strategy = strategy
        self.check = check
        self.tried = 0
        self.working = 0  # command lines accepted and still at work after 5 s
        self.slowest_s = 0.0
        self.failures: dict[str, str] = {}  # kind -> one shrunk example's message

    def run_one(self, value) -> None:
        self.tried += 1
        started = time.perf_counter()
        if self.check(value) == command_line.WORKING:
            self.working += 1
            return
        self.slowest_s = max(self.slowest_s, time.perf_counter() - started)

    def figures(self) -> dict[str, object]:
        return {
            "boundary": self.name,
            "inputs_tried": self.tried,
            "still_working_after_5_s": self.working,
            "distinct_failures": len(self.failures),
            "slowest_answer_s": round(self.slowest_s, 4),
            "failures": self.failures,
        }


def boundaries(folder: Path, amplifier) -> dict[str, Boundary]:
    recording = folder / "small.h5"
    b.write_small_recording(recording)
    files = command_line.inputs(folder)
    names = list(command_line.commands())

    def in_scratch(check: Callable[..., object]) -> Callable[..., object]:
        def run(value) -> object:
            with tempfile.TemporaryDirectory(dir=folder) as scratch:
                return check(value, Path(scratch))

        return run

    return {
        "frames": Boundary("frames", b.frame_streams(), lambda v: b.check_frames(*v)),
        "exchange": Boundary(
            "exchange", b.exchange_files(), in_scratch(lambda v, d: b.check_exchange(*v, d))
        ),
        "rig_file": Boundary("rig_file", b.rig_files(), b.check_rig_file),
        "recording": Boundary(
            "recording",
            b.DAMAGES,
            in_scratch(lambda v, d: b.check_damaged_recording(recording, v, d)),
        ),
        "modbus_driver": Boundary(
            "modbus_driver", modbus.driver_cases(), lambda v: modbus.check_driver(amplifier, v)
        ),
        "modbus_server": Boundary(
            "modbus_server",
            modbus.hostile_requests(),
            lambda v: modbus.check_server(amplifier, v),
        ),
        "cli": Boundary(
            "cli",
            st.sampled_from(names).flatmap(lambda name: command_line.command_lines(name, files)),
            in_scratch(lambda v, d: command_line.check_command_line(v, d)),
        ),
    }


def kind_of(error: BaseException) -> str:
    """A failure's kind: its type and the first words of its message (numbers dropped)."""
    words = "".join(c if not c.isdigit() else "#" for c in str(error).split("\n")[0])[:90]
    return f"{type(error).__name__}: {words}"


def fuzz(boundary: Boundary, seconds: float, round_size: int) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:

        @settings(
            max_examples=round_size,
            derandomize=False,
            database=None,
            deadline=None,
            suppress_health_check=list(HealthCheck),
            report_multiple_bugs=False,
        )
        @given(boundary.strategy)
        def one_round(value) -> None:
            boundary.run_one(value)

        try:
            one_round()
        except HypothesisException as error:  # Hypothesis itself (e.g. flaky): count it too
            boundary.failures.setdefault(kind_of(error), str(error)[:400])
        except Exception as error:  # a bad answer, shrunk: one of each kind is kept
            boundary.failures.setdefault(kind_of(error), str(error)[:400])


def save_rows(results: list[dict[str, object]], load: float) -> None:
    """Write each results file of :data:`SAVED` whose boundaries ran: inputs tried, distinct
    bad answers and the slowest answer per boundary, in one row."""
    by_name = {row["boundary"]: row for row in results}
    for key, start, labels in SAVED:
        ran = [by_name[name] for name in labels if name in by_name]
        if not ran:
            continue
        bad = sum(row["distinct_failures"] for row in ran)
        kinds = [kind for row in ran for kind in row["failures"]]
        working = sum(row["still_working_after_5_s"] for row in ran)
        now = (" / ".join(f"{row['inputs_tried']:,}" for row in ran) + " inputs; "
               + f"{bad} bad answers" + (f" ({'; '.join(kinds)})" if kinds else "") + "; slowest "
               + " / ".join(f"{row['slowest_answer_s']:.2f}" for row in ran) + " s"
               + (f" ({working:,} command lines accepted and still at work after 5 s, killed "
                  "and not judged)" if working else ""))
        what = start.format(" / ".join(labels[row["boundary"]] for row in ran))
        save(result(key, [figure(what + "inputs tried, distinct bad answers, slowest answer",
                                 now, GOAL)], load_at_start=load))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=1.0, help="per boundary (1)")
    parser.add_argument(
        "--boundary",
        action="append",
        choices=BOUNDARIES,
        help="only this boundary (repeat for several; default: all)",
    )
    parser.add_argument("--round", type=int, default=200, help="examples per Hypothesis round")
    parser.add_argument("--json", type=Path, help="also write the figures to this file")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/fuzz.json and "
                        "fuzz-hardware-and-cli.json")
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    results = []
    amplifier = modbus.amplifier()
    with tempfile.TemporaryDirectory(prefix="impact-rig-fuzz-") as folder:
        known = boundaries(Path(folder), amplifier)
        for name in args.boundary or list(known):
            boundary = known[name]
            fuzz(boundary, args.minutes * 60.0, args.round)
            figures = boundary.figures()
            results.append(figures)
            working = f", {boundary.working:,} still at work after 5 s" if boundary.working else ""
            print(
                f"{name}: {figures['inputs_tried']:,} inputs tried, "
                f"{figures['distinct_failures']} distinct failures, slowest answer "
                f"{figures['slowest_answer_s']:.3f} s{working}",
                flush=True,
            )
            for kind, example in boundary.failures.items():
                print(f"  {kind}\n    {example[:300]}", flush=True)
    amplifier.stop()
    summary = {"minutes_per_boundary": args.minutes, "boundaries": results}
    text = json.dumps(summary)
    print(text)
    if args.json is not None:
        args.json.write_text(text + "\n", encoding="utf-8")
    if args.save:
        save_rows(results, load)
    return 1 if any(r["distinct_failures"] for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
