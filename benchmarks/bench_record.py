"""Recording at full rate: 4 channels at 200 kHz through the real transport into HDF5.

The DAQ board emulator runs in its own process (a counter source on a pty, its
cost not counted); this process runs what a lab PC runs: the serial driver and
role drivers (4 analog inputs + tachometer), the acquisition engine and the
recorder (SWMR HDF5, gzip-1 + shuffle, flushed every 0.5 s).  A third process
reads the file with SWMR while it is written and measures, for every block, the
delay from its arrival in the engine to its being readable.

Reported: samples lost (goal 0), CPU share of this process, bytes on disk per
stored sample, SWMR delay (goal under 1.5 s).  Baseline measured in the same run:
the same acquisition with a subscriber that drops the data instead of recording
it, so the ratio is what recording costs on top of acquiring.

    python benchmarks/bench_record.py --seconds 10      (full run: 60 s)
    python benchmarks/bench_record.py --save            (also benchmarks/results/record.json
                                                         and record-live-rate.json)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
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
from harness.results import figure, result, save  # noqa: E402
from rig.engine import AcquisitionEngine  # noqa: E402
from rig.recorder import (  # noqa: E402
    ChannelSpec,
    Recorder,
    RecordingMetadata,
    attach_recorder,
)

RATE_HZ = 200_000.0
CHANNELS = (0, 1, 2, 3)
GOAL_DELAY_S = 1.5
POLL_S = 0.05


def open_board(port: str):
    board = DaqBoard(SerialDaqBackend(port), sample_rate_hz=RATE_HZ, analog_channels=CHANNELS)
    roles = [
        PotentiometerAngleSensor(board, 0, PotentiometerCalibration()),
        LaserDisplacementSensor(board, 1, LaserCalibration()),
        AnalogVoltageInput(board, 2),
        AnalogVoltageInput(board, 3),
        Tachometer(board),
    ]
    board.open()
    return board, roles


def specs(fs: float) -> list[ChannelSpec]:
    return [
        ChannelSpec("angle", unit="rad", sample_rate_hz=fs, raw_dtype="int16"),
        ChannelSpec("table", unit="m", sample_rate_hz=fs, raw_dtype="int16"),
        ChannelSpec("ai2", unit="V", sample_rate_hz=fs, raw_dtype="int16"),
        ChannelSpec("ai3", unit="V", sample_rate_hz=fs, raw_dtype="int16"),
        ChannelSpec("tach", kind="pulses", sample_rate_hz=fs),
    ]


def run(seconds: float, path: Path | None, compression: str | None = "auto") -> dict:
    """Acquire for ``seconds``; record into ``path`` (or drop everything when None)."""
    emulator = EmulatorProcess("--samples-per-frame", "1024")
    reader = None
    try:
        board, roles = open_board(emulator.port)
        engine = AcquisitionEngine(roles)
        recorder = thread = drain = None
        if path is not None:
            recorder = Recorder(
                path,
                specs(board.sample_rate_hz),
                RecordingMetadata("forced", notes="bench_record"),
                compression=compression,
            )
            thread = attach_recorder(engine, recorder)
        else:
            sink = engine.subscribe("sink", privileged=True)

            def drop() -> None:
                while not sink.closed:
                    sink.get_many(0.1)

            drain = threading.Thread(target=drop, daemon=True)
            drain.start()
        cpu0, wall0 = time.process_time(), time.monotonic()
        engine.start()
        if path is not None:
            # the engine's host_time_s counts from its start; the reader shares the clock
            reader = subprocess.Popen(
                [sys.executable, __file__, "--reader", str(path), repr(engine._t0)],
                cwd=ROOT,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                text=True,
            )
        while time.monotonic() - wall0 < seconds and engine.error is None:
            time.sleep(0.2)
        stats = engine.stats()
        engine.stop()
        if thread is not None:
            thread.join(30)
            recorder.close()
        if drain is not None:
            drain.join(5)
        wall = time.monotonic() - wall0
        cpu = time.process_time() - cpu0
        board.close()
        result = {
            "seconds": wall,
            "cpu_share": cpu / wall,
            "samples": sum(
                stats.channels[c].samples_received for c in ("angle", "table", "ai2", "ai3")
            ),
            "lost": stats.samples_lost,
            # the live rate estimate (status panel, tests assert only that there is one)
            "estimated_rate_hz": stats.channels["angle"].sample_rate_hz,
            "board_lost": board.status().samples_lost,
            "error": stats.error,
        }
        if reader is not None:
            reader.stdin.close()
            result["swmr"] = json.loads(reader.stdout.read() or "{}")
            reader.wait(10)
        if path is not None:
            result["bytes"] = path.stat().st_size
        return result
    finally:
        emulator.close()


def read_while_written(path: str, origin: float) -> None:
    """Reader process: poll the file with SWMR; for each new block of 'angle', how long after
    its arrival in the engine it became readable.  Prints a JSON summary when stdin closes."""
    import h5py

    stop = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), stop.set()), daemon=True).start()
    delays: list[float] = []
    seen = 0
    f = None
    while not stop.is_set():
        time.sleep(POLL_S)
        try:
            if f is None:
                f = h5py.File(path, "r", libver="latest", swmr=True)
                blocks = f["channels"]["angle"]["blocks"]
                seen = blocks.shape[0]  # rows written before this reader was ready: not timed
                continue
            blocks.refresh()
            n = blocks.shape[0]
            if n > seen:
                now = time.monotonic() - origin
                arrived = blocks[seen:n]["host_time_s"]
                delays.extend((now - arrived).tolist())
                seen = n
        except (OSError, KeyError):
            continue
    if f is not None:
        f.close()
    summary = {
        "blocks": len(delays),
        "max_s": max(delays) if delays else None,
        "mean_s": sum(delays) / len(delays) if delays else None,
    }
    print(json.dumps(summary), flush=True)


def realistic_bytes_per_sample(compression: str | None, seconds: float = 5.0) -> float:
    """Bytes per sample for rig-like content: a swinging angle and a sine table with ADC noise
    (a few counts), written by the recorder directly (no transport), 4 channels at 200 kHz."""
    import numpy as np

    from drivers.interfaces import SampleBlock

    rng = np.random.default_rng(1)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "content.h5"
        recorder = Recorder(
            path, specs(RATE_HZ)[:4], RecordingMetadata("forced"), compression=compression
        )
        block = 2048
        n_blocks = int(seconds * RATE_HZ) // block
        for k in range(n_blocks):
            index = np.arange(k * block, (k + 1) * block)
            t = index / RATE_HZ
            for c, name in enumerate(("angle", "table", "ai2", "ai3")):
                signal = 3000 * np.sin(2 * np.pi * (2.3 + c) * t) + rng.normal(0, 3, block)
                raw = signal.astype(np.int16)
                recorder.add(
                    SampleBlock(name, int(index[0]), float(t[0]), RATE_HZ, raw, raw * 1e-4),
                    float(t[0]),
                )
            if recorder.flush_due:
                recorder.flush()
        recorder.close()
        return path.stat().st_size / (4 * n_blocks * block)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="recording length (60)")
    parser.add_argument(
        "--baseline-seconds",
        type=float,
        default=None,
        help="acquisition-only baseline length (default: min(10, --seconds))",
    )
    parser.add_argument(
        "--compression",
        choices=("auto", "gzip", "lzf", "none"),
        default="auto",
        help="recorder compression (auto: lzf at 200 kHz)",
    )
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/record.json and "
                        "record-live-rate.json")
    parser.add_argument("--reader", nargs=2, metavar=("FILE", "ORIGIN"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.reader:
        read_while_written(args.reader[0], float(args.reader[1]))
        return 0
    load = os.getloadavg()[0]
    baseline_s = args.baseline_seconds or min(10.0, args.seconds)
    compression = None if args.compression == "none" else args.compression
    print(
        f"load average before the run: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; "
        f"compression {args.compression}"
    )
    print(
        f"4 analog channels + tach at {RATE_HZ:,.0f} Hz over a pty, emulator in its own "
        f"process; {args.seconds:g} s recorded, {baseline_s:g} s baseline"
    )
    base = run(baseline_s, None)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bench.h5"
        rec = run(args.seconds, path, compression)
    print(
        f"baseline (acquire, drop): CPU {base['cpu_share']:.1%} of a core, "
        f"{base['samples']:,} samples, {base['lost']} lost"
    )
    print(
        f"recording:                CPU {rec['cpu_share']:.1%} of a core, "
        f"{rec['samples']:,} samples, {rec['lost']} lost (board: {rec['board_lost']})"
        + (f", error: {rec['error']}" if rec["error"] else "")
    )
    print(
        f"live rate estimate while recording: {rec['estimated_rate_hz']:,.0f} Hz of "
        f"{RATE_HZ:,.0f} Hz ({rec['estimated_rate_hz'] / RATE_HZ - 1:+.1%})"
    )
    print(f"recording / baseline CPU: {rec['cpu_share'] / max(base['cpu_share'], 1e-9):.2f}x")
    print(
        f"on disk: {rec['bytes']:,} bytes, {rec['bytes'] / max(rec['samples'], 1):.3f} bytes "
        "per stored sample (counter-source data: highly compressible; all datasets counted)"
    )
    rig_like = realistic_bytes_per_sample(compression)
    print(
        f"rig-like content (swinging signals + ADC noise of a few counts): "
        f"{rig_like:.2f} bytes per sample "
        "(raw int16 + float32 + uint8 flags = 7 bytes uncompressed)"
    )
    swmr = rec.get("swmr") or {}
    if swmr.get("max_s") is not None:
        verdict = "met" if swmr["max_s"] < GOAL_DELAY_S else "NOT met"
        print(
            f"SWMR reader: {swmr['blocks']:,} blocks, delay arrival -> readable mean "
            f"{swmr['mean_s']:.3f} s, max {swmr['max_s']:.3f} s (goal < {GOAL_DELAY_S} s: "
            f"{verdict}; includes the reader's {POLL_S} s polling)"
        )
    goal = "met" if rec["lost"] == 0 and not rec["error"] else "NOT met"
    print(f"zero lost samples: {goal}")
    if args.save:
        delay = (f"{swmr['mean_s']:.2f} s mean, {swmr['max_s']:.1f} s max"
                 if swmr.get("max_s") is not None else "not measured (no reader summary)")
        lost = f"{rec['lost']:,} of {rec['samples'] / 1e6:.0f} M" + (
            f" (stopped: {rec['error']})" if rec["error"] else "")
        save(result("record", [
            figure(f"4 x {RATE_HZ / 1e3:.0f} kHz through a pty into HDF5 for "
                   f"{args.seconds:g} s: samples lost", lost),
            figure("CPU", f"{rec['cpu_share']:.0%} of a core "
                          f"({rec['cpu_share'] / max(base['cpu_share'], 1e-9):.2f}x acquiring "
                          "alone)"),
            figure("file size for rig-like signals", f"{rig_like:.1f} bytes per sample"),
            figure("SWMR reader delay", delay),
        ], load_at_start=load))
        save(result("record-live-rate", [
            figure(f"the live rate estimate (status panel) while recording "
                   f"{RATE_HZ / 1e3:.0f} kHz",
                   f"{rec['estimated_rate_hz']:,.0f} Hz "
                   f"({rec['estimated_rate_hz'] / RATE_HZ - 1:+.1%})"),
        ], load_at_start=load))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("HDF5_USE_FILE_LOCKING", "FALSE")
    sys.exit(main())
