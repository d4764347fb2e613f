"""Sustained DAQ streaming through a pty: highest loss-free rate, and CPU per second of data.

The board emulator runs in a separate process (its cost is not counted); this
process runs the real driver stack: serial backend (sync scan, CRC, numpy
decoding), DaqBoard (gap counting, fan-out) and five role drivers with their
calibrations (angle, laser with range flags, two spare voltage inputs, tachometer
edges), read by the main thread as an application would.

For each rate of a ladder, stream ``--seconds`` (60 for the full run) and report
samples received and lost, frames rejected, and the process CPU time per second
of data.  Baseline, measured in the same run at the CPU-figure rate: a bare
reader that only pulls the same bytes off the pty (select + os.read), so the
ratio shows what parsing and calibration cost on top of moving the bytes.

The board is the Python emulator and the C firmware core's host build (firmware/,
compiled with gcc into a temporary directory), each on its own pty, the driver unchanged
in front of both (``--boards`` picks); ``--json PATH`` also writes the figures, and
``--save`` writes them for the benchmarks page to ``benchmarks/results/daq-stream.json``
(harness/results.py).

    python benchmarks/bench_daq_stream.py --seconds 5 --json daq_stream.json
    python benchmarks/bench_daq_stream.py --save
"""

from __future__ import annotations

import argparse
import json
import os
import select
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.emulator_process import EmulatorProcess  # noqa: E402
from drivers.daq import DaqBoard  # noqa: E402
from drivers.sensors import (  # noqa: E402
    AnalogVoltageInput,
    LaserCalibration,
    LaserDisplacementSensor,
    PotentiometerAngleSensor,
    PotentiometerCalibration,
    Tachometer,
)
from drivers.serial_daq import SerialDaqBackend  # noqa: E402
from harness.firmware_host import (  # noqa: E402
    HOST_IDENTITY,
    FirmwareBoard,
    build_host_firmware,
)
from harness.results import figure, result, save  # noqa: E402

BOARDS = ("emulator", "firmware")

CHANNELS = (0, 1, 2, 3)
LADDER_HZ = (40_000, 100_000, 150_000, 200_000, 250_000)
BOARD_MAX_RATE_HZ = 250_000  # the IRDAQ-4's limit; rates above it emulate a faster board
HEADROOM_HZ = (400_000, 600_000, 800_000)
CPU_FIGURE_RATE_HZ = 40_000
GOAL_RATE_HZ = 200_000
GOAL_CPU_FRACTION = 0.25


@dataclass
class Result:
    rate_hz: float
    seconds: float
    samples: int
    lost: int
    rejected: int
    cpu_s: float

    @property
    def data_seconds(self) -> float:
        return self.samples / self.rate_hz

    @property
    def cpu_per_data_second(self) -> float:
        return self.cpu_s / self.data_seconds if self.samples else float("nan")


class FirmwareProcess:
    """The firmware core's host build in real time, as :class:`EmulatorProcess` is used."""

    binary: Path | None = None

    def __init__(self, *extra_args: str) -> None:
        if FirmwareProcess.binary is None:
            FirmwareProcess.binary = build_host_firmware(Path(tempfile.mkdtemp()))
        max_rate = float(extra_args[1]) if extra_args[:1] == ("--max-rate-hz",) else None
        identity = (
            HOST_IDENTITY
            if max_rate is None
            else HOST_IDENTITY.__class__(**{**HOST_IDENTITY.__dict__, "max_rate_hz": max_rate})
        )
        self.board = FirmwareBoard(FirmwareProcess.binary, speed=1.0, identity=identity).start()
        self.port = self.board.port

    def close(self) -> None:
        self.board.close()


def start_board(kind: str, *args: str) -> EmulatorProcess | FirmwareProcess:
    return FirmwareProcess(*args) if kind == "firmware" else EmulatorProcess(*args)


def stream(rate_hz: float, seconds: float, board_kind: str = "emulator") -> Result:
    emulator = start_board(board_kind, "--max-rate-hz", f"{max(BOARD_MAX_RATE_HZ, rate_hz):g}")
    try:
        board = DaqBoard(
            SerialDaqBackend(emulator.port), sample_rate_hz=rate_hz, analog_channels=CHANNELS
        )
        roles = [
            PotentiometerAngleSensor(board, 0, PotentiometerCalibration(linearity=(0.01, -0.02))),
            LaserDisplacementSensor(board, 1, LaserCalibration()),
            AnalogVoltageInput(board, 2),
            AnalogVoltageInput(board, 3),
            Tachometer(board),
        ]
        board.open()
        cpu0, wall0 = time.process_time(), time.monotonic()
        board.start_roles(*roles)
        samples = 0
        while time.monotonic() - wall0 < seconds:
            for role in roles:
                block = role.read(0.02)
                if block is not None and role is roles[0]:
                    samples += len(block)
        status = board.status()
        # A role read too slowly drops its oldest samples: lost too, though the board
        # received them.  Each role's count holds the board's gaps plus its own drops.
        lost = max(status.samples_lost, *(role.status().samples_lost for role in roles))
        for role in roles:
            role.stop()
        cpu = time.process_time() - cpu0
        board.close()
        return Result(rate_hz, seconds, samples, lost, status.frames_rejected, cpu)
    finally:
        emulator.close()


def bare_read_cpu(
    rate_hz: float, seconds: float, board_kind: str = "emulator"
) -> tuple[float, int]:
    """Baseline: CPU to pull the same stream off the pty without looking at it."""
    emulator = start_board(board_kind, "--max-rate-hz", f"{BOARD_MAX_RATE_HZ:g}")
    try:
        backend = SerialDaqBackend(emulator.port)
        backend.connect()
        backend.configure(rate_hz, CHANNELS)
        backend.start()
        port = backend._serial  # the open port: read its file descriptor directly
        assert port is not None
        fd = port.fileno()
        received = 0
        cpu0, wall0 = time.process_time(), time.monotonic()
        while time.monotonic() - wall0 < seconds:
            readable, _, _ = select.select([fd], [], [], 0.05)
            if readable:
                received += len(os.read(fd, 1 << 16))
        cpu = time.process_time() - cpu0
        backend.close()
        return cpu, received
    finally:
        emulator.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="per rate (full run: 60)")
    parser.add_argument(
        "--rates", type=float, nargs="+", default=LADDER_HZ, help="per-channel rates (Hz)"
    )
    parser.add_argument(
        "--headroom",
        action="store_true",
        help=f"also try {', '.join(f'{r:,}' for r in HEADROOM_HZ)} Hz on an emulated faster "
        "board, to find where the host (or the Python emulator) gives out",
    )
    parser.add_argument("--boards", nargs="+", choices=BOARDS, default=list(BOARDS))
    parser.add_argument("--json", type=Path, default=None, help="also write the figures here")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/daq-stream.json")
    args = parser.parse_args(argv)
    if args.headroom:
        args.rates = [*args.rates, *HEADROOM_HZ]
    load = os.getloadavg()[0]
    figures = {"command": sys.argv, "seconds": args.seconds, "boards": {}}
    for board_kind in args.boards:
        figures["boards"][board_kind] = run_board(board_kind, args)
    if args.json is not None:
        args.json.write_text(json.dumps(figures, indent=2) + "\n")
        print(f"\nfigures written to {args.json}")
    if args.save:
        rows = [row for board_kind, board in figures["boards"].items()
                for row in page_rows(board_kind, board, args.seconds)]
        save(result("daq-stream", rows, load_at_start=load))
    return 0


def page_rows(board_kind: str, board: dict, seconds: float) -> list[dict[str, str]]:
    """One board's figures as rows of the benchmarks page."""
    rows = []
    goal = next((r for r in board["rates"] if r["rate_hz"] == GOAL_RATE_HZ), None)
    if goal is not None:
        rows.append(figure(
            f"{board_kind}: pty + serial driver + calibration, 4 channels at "
            f"{GOAL_RATE_HZ / 1000:g} kHz for {seconds:g} s",
            f"{goal['lost']} samples lost, {100 * goal['cpu_s_per_data_s']:.0f} % of one core",
            f"0 lost, < {100 * GOAL_CPU_FRACTION:.0f} % of one core"))
    ratio = board["cpu_s_per_data_s_at_figure_rate"] / max(board["bare_read_cpu_s_per_s"], 1e-9)
    rows.append(figure(
        f"{board_kind}: 4 channels at {CPU_FIGURE_RATE_HZ / 1000:g} kHz",
        f"{board['cpu_s_per_data_s_at_figure_rate']:.3f} CPU s per s of data "
        f"({ratio:.1f}x a bare read)"))
    best = board["highest_zero_loss_rate_hz"]
    tried = ", ".join(f"{r['rate_hz'] / 1000:g}" for r in board["rates"])
    shown = f"4 x {best / 1000:g} kHz" if best else "none"
    if best == BOARD_MAX_RATE_HZ:
        shown += " (the board's maximum)"
    elif best > BOARD_MAX_RATE_HZ:
        shown += " (an emulated faster board)"
    rows.append(figure(f"{board_kind}: highest rate with zero loss (of {tried} kHz)", shown))
    return rows


def run_board(board_kind: str, args: argparse.Namespace) -> dict:
    """The ladder, the CPU figure and the goal for one board; its figures as data."""
    print(f"\nboard: {board_kind}; 4 channels + digital word, 256-sample frames, "
          f"{args.seconds:g} s per rate")  # fmt: skip
    print(f"{'rate/ch':>10} {'aggregate':>10} {'samples':>10} {'lost':>6} {'rejected':>8} "
          f"{'cpu s/data s':>12}")  # fmt: skip
    results = []
    for rate in args.rates:
        result = stream(rate, args.seconds, board_kind)
        results.append(result)
        print(
            f"{rate:>10,.0f} {4 * rate:>10,.0f} {result.samples:>10,} {result.lost:>6} "
            f"{result.rejected:>8} {result.cpu_per_data_second:>12.3f}",
            flush=True,
        )
    clean = [r.rate_hz for r in results if r.lost == 0 and r.rejected == 0 and r.samples]
    best = max(clean, default=0.0)
    print(f"highest rate with zero loss: 4 x {best:,.0f} Hz = {4 * best:,.0f} samples/s")

    at_figure = next((r for r in results if r.rate_hz == CPU_FIGURE_RATE_HZ), None)
    if at_figure is None:
        at_figure = stream(CPU_FIGURE_RATE_HZ, args.seconds, board_kind)
    base_cpu, base_bytes = bare_read_cpu(CPU_FIGURE_RATE_HZ, args.seconds, board_kind)
    base_per_data_s = base_cpu / args.seconds
    ratio = at_figure.cpu_per_data_second / max(base_per_data_s, 1e-9)
    print(
        f"CPU at 4 x {CPU_FIGURE_RATE_HZ:,} Hz: driver stack {at_figure.cpu_per_data_second:.3f} "
        f"s per s of data; bare pty read {base_per_data_s:.3f} s/s ({base_bytes:,} bytes); "
        f"ratio {ratio:.1f}x"
    )
    goal = next((r for r in results if r.rate_hz == GOAL_RATE_HZ), None)
    goal_met = None
    if goal is not None:
        goal_met = goal.lost == 0 and goal.cpu_per_data_second < GOAL_CPU_FRACTION
        print(
            f"goal 4 x {GOAL_RATE_HZ:,} Hz, zero loss, < {GOAL_CPU_FRACTION:.0%} of a core: "
            f"{'met' if goal_met else 'NOT met'} (lost {goal.lost}, "
            f"{goal.cpu_per_data_second:.1%} of a core)"
        )
    return {
        "rates": [
            {
                "rate_hz": r.rate_hz,
                "samples": r.samples,
                "lost": r.lost,
                "rejected": r.rejected,
                "cpu_s_per_data_s": r.cpu_per_data_second,
            }
            for r in results
        ],
        "highest_zero_loss_rate_hz": best,
        "cpu_s_per_data_s_at_figure_rate": at_figure.cpu_per_data_second,
        "bare_read_cpu_s_per_s": base_per_data_s,
        "goal_met": goal_met,
    }


if __name__ == "__main__":
    sys.exit(main())
