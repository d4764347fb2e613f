"""Soak: a long recording from the virtual rig over its real wire protocols, faults injected.

The DAQ board emulator on a pty (reached through a stable symlink, as a udev by-id
link) and the amplifier's Modbus TCP server run in their own process; this process runs
the serial driver, the acquisition engine, the HDF5 recorder and the Modbus shaker
driver (``harness.soak`` says how).  Every ``--fault-every`` seconds one fault in
turn: garbled frames (random bytes, CRCs flipped), the board unplugged for a second and
plugged in again (reset), the amplifier's controller restarted.  Halfway between faults
another process opens the file being written.

Printed: resident memory growth after warm-up (this process), CPU share, samples lost
outside the fault windows (goal 0), every fault window in the file (garbled frames as
gaps, unplugs as outages with their length, amplifier losses as drive-off rows), stored
samples that repeat an index, and whether the file reads (the project's reader, h5py,
``impact-rig export``); the figures also as one JSON line (``--json FILE`` writes it), and
with ``--save`` as the benchmarks page's row (benchmarks/results/soak.json).
The exit status is 1 when a goal is missed.

    python benchmarks/soak.py                       (an hour at 200 kHz)
    python benchmarks/soak.py --minutes 10 --fault-every 20
    python benchmarks/soak.py --minutes 16 --rate 50000 --save
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from harness.results import figure, result, save
from harness.soak import SoakFigures, run_soak

GOAL_RSS_GROWTH_PCT = 5.0


def missed(figures: SoakFigures) -> list[str]:
    """The goals a run missed, in words."""
    checks = [
        (figures.rss_growth_pct < GOAL_RSS_GROWTH_PCT, "resident memory grew 5 % or more"),
        (figures.samples_lost_outside_fault_windows == 0, "samples lost outside fault windows"),
        (figures.injected_windows_in_file == figures.injected_windows, "garbled frames unseen"),
        (figures.outages_in_file == figures.unplugs, "an unplug without its outage row"),
        (figures.gaps_table_matches_blocks, "the gaps table disagrees with the stored blocks"),
        (figures.duplicated_samples == 0, "a sample stored twice"),
        (
            len(figures.amplifier_windows) == figures.amplifier_restarts
            and figures.drive_off_rows_in_file == figures.amplifier_restarts,
            "an amplifier restart not seen, not recovered or not in the drive log",
        ),
        (not figures.watch_error, f"the shaker driver raised {figures.watch_error}"),
        (not figures.live_reads_failed, "the file did not read while written"),
        (figures.reader_ok and figures.h5py_ok, "the file does not read after"),
        (figures.export_ok, f"impact-rig export failed: {figures.export_message}"),
    ]
    return [words for ok, words in checks if not ok]


def row(f: SoakFigures) -> dict[str, str]:
    """The benchmarks page's row of a run."""
    kinds = [kind for _, kind in f.faults]
    every = "a fault a minute" if f.fault_every_s == 60 else f"a fault every {f.fault_every_s:g} s"
    what = (f"{f.seconds / 60:g} min from the virtual rig (2 channels + tach at "
            f"{f.sample_rate_hz / 1e3:g} kHz, pty + Modbus TCP), {every} "
            f"({kinds.count('garbled')} garbled, {f.unplugs} unplugs, {f.amplifier_restarts} "
            "amplifier restarts): memory growth after warm-up / lost outside fault windows / "
            "windows in the file / stored twice / file read")
    by_log = ", ".join(f"{kind} {count:,}" for kind, count in f.lost_outside_by_board_log.items())
    rows, restarts = f.drive_off_rows_in_file, f.amplifier_restarts
    drive_off = (f"drive-off rows for {rows} of {restarts} restarts" if rows < restarts else
                 f"drive-off rows for {restarts} restarts"
                 + (f" and {rows - restarts} more link losses" if rows > restarts else ""))
    after = {"reader": f.reader_ok, f"h5py {f.h5py_version}": f.h5py_ok, "export": f.export_ok}
    failed = [name for name, ok in after.items() if not ok]
    reads = (f"{f.live_reads_ok} reads while written"
             + (f" ({len(f.live_reads_failed)} failed)" if f.live_reads_failed else "")
             + f", {', '.join(after)} "
             + ("all ok" if not failed else f"failed: {', '.join(failed)}"))
    now = " / ".join([
        f"{f.rss_growth_pct:.2f} % ({f.rss_warm_mb:.1f} to {f.rss_end_mb:.1f} MB)",
        f"{f.samples_lost_outside_fault_windows:,} samples" + (f" (board log: {by_log})"
                                                               if by_log else ""),
        f"{f.injected_windows_in_file} of {f.injected_windows} garbled frames, "
        f"{f.outages_in_file} of {f.unplugs} outages, {drive_off}",
        f"{f.duplicated_samples:,}",
        reads,
    ])
    return figure(what, now, "under 5 %, 0 lost, every window, over an hour at 200 kHz")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0, help="how long to record (60)")
    parser.add_argument(
        "--fault-every", type=float, default=60.0, metavar="S", help="seconds between faults (60)"
    )
    parser.add_argument(
        "--rate", type=float, default=200_000.0, help="the board's sample rate, Hz (200000)"
    )
    parser.add_argument(
        "--warmup", type=float, metavar="S", help="seconds before memory counts (a sixth, <= 300)"
    )
    parser.add_argument("--folder", type=Path, help="where the recording goes (a temporary one)")
    parser.add_argument("--json", type=Path, help="also write the figures to this file")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/soak.json")
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    if not (args.minutes > 0 and args.fault_every > 0 and args.rate > 0):
        parser.error("--minutes, --fault-every and --rate must be positive")
    with tempfile.TemporaryDirectory(prefix="impact-rig-soak-", dir=args.folder) as folder:
        figures = run_soak(
            Path(folder),
            args.minutes * 60.0,
            fault_every_s=args.fault_every,
            rate_hz=args.rate,
            warmup_s=args.warmup,
            progress=lambda text: print(text, flush=True),
        )
    f = figures
    print(
        f"{f.seconds / 60:g} min at {f.sample_rate_hz:,.0f} Hz, {len(f.faults)} faults: "
        f"{f.samples_stored:,} samples stored per channel, {f.file_bytes / 1e6:,.0f} MB\n"
        f"resident memory {f.rss_warm_mb} MB after warm-up, {f.rss_end_mb} MB at the end "
        f"(max {f.rss_max_mb}): growth {f.rss_growth_pct} %; CPU {f.cpu_share_of_one_core:.0%} "
        "of one core\n"
        f"samples lost: {f.samples_lost:,} in fault windows "
        f"{f.samples_lost_in_fault_windows:,}, outside {f.samples_lost_outside_fault_windows:,}"
        f" {f.lost_outside_by_board_log or ''}\n"
        f"garbled frames in the file as gaps: {f.injected_windows_in_file}/{f.injected_windows};"
        f" unplugs with an outage row: {f.outages_in_file}/{f.unplugs}; amplifier restarts "
        f"recovered: {len(f.amplifier_windows)}/{f.amplifier_restarts} (drive-off rows "
        f"{f.drive_off_rows_in_file}); gaps table = stored blocks: {f.gaps_table_matches_blocks};"
        f" samples stored twice: {f.duplicated_samples}\n"
        f"read while written: {f.live_reads_ok} ok, {len(f.live_reads_failed)} failed; after: "
        f"reader {f.reader_ok}, h5py {f.h5py_version} {f.h5py_ok}, export {f.export_ok}",
        flush=True,
    )
    problems = missed(figures)
    for problem in problems:
        print(f"MISSED: {problem}")
    text = json.dumps({**asdict(figures), "missed": problems})
    print(text)
    if args.json is not None:
        args.json.write_text(text + "\n", encoding="utf-8")
    if args.save:
        save(result("soak", [row(figures)], load_at_start=load))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
