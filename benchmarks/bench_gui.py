"""The desktop application while streaming 4 x 40 kHz and recording: frame rate, GUI-thread
latency, and lost samples.

The DAQ board emulator runs in its own process (it stands for the external board);
this process runs what a lab PC runs: the real serial driver stack (four analog
roles and the tachometer), the acquisition engine, the HDF5 recorder on its thread,
and the main window (offscreen) drawing at its 30 Hz frame timer while cycling
through the views.  Measured:

- frames per second actually drawn, and the frame-to-frame interval (p50/p99/max);
- event-loop latency: how late a zero-delay timer posted every 50 ms runs;
- samples lost by the engine (device to host) and by the recording, and what the
  GUI's own bounded queue skipped (display only).

Baseline, measured in the same run: the same streaming and recording without the
window, so the CPU ratio shows what the display costs on top of acquisition.

    python benchmarks/bench_gui.py --seconds 10      # full run: --seconds 60
    python benchmarks/bench_gui.py --save            # also benchmarks/results/gui.json
Goal: 0 lost, >= 30 fps on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault(
    "IMPACT_RIG_GUI_SETTINGS", str(Path(tempfile.mkdtemp(prefix="bench-gui-")) / "gui.ini")
)

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

RATE_HZ = 40_000.0
CHANNELS = (0, 1, 2, 3)
GOAL_FPS = 30.0
VIEW_PERIOD_S = 5.0  # how long each view stays in front


class Rig:
    """Board, roles, engine and a recording: everything but the window."""

    def __init__(self, port: str, path: Path) -> None:
        self.board = DaqBoard(
            SerialDaqBackend(port), sample_rate_hz=RATE_HZ, analog_channels=CHANNELS
        )
        self.streams = [
            PotentiometerAngleSensor(self.board, 0, PotentiometerCalibration()),
            LaserDisplacementSensor(self.board, 1, LaserCalibration()),
            AnalogVoltageInput(self.board, 2, "spare2"),
            AnalogVoltageInput(self.board, 3, "spare3"),
            Tachometer(self.board),
        ]
        self.board.open()
        fs = self.board.sample_rate_hz
        specs = [
            ChannelSpec("angle", "samples", "rad", fs, raw_dtype="int16"),
            ChannelSpec("table", "samples", "m", fs, raw_dtype="int16"),
            ChannelSpec("spare2", "samples", "V", fs, raw_dtype="int16"),
            ChannelSpec("spare3", "samples", "V", fs, raw_dtype="int16"),
            ChannelSpec("tach", "pulses", "", fs),
        ]
        self.engine = AcquisitionEngine(self.streams)
        self.recorder = Recorder(path, specs, RecordingMetadata(experiment="forced"))
        self.writer = attach_recorder(self.engine, self.recorder)

    def start(self) -> None:
        self.engine.start()

    def stop(self) -> tuple[int, int, int]:
        """Stop; (samples received on the angle, lost by the engine, lost in the file)."""
        self.engine.stop()
        self.writer.join(30.0)
        stats = self.engine.stats()
        self.recorder.close("benchmark done")
        self.board.close()
        return (
            stats.channels["angle"].samples_received,
            stats.samples_lost,
            self.recorder.samples_lost,
        )


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


def run_without_gui(seconds: float, folder: Path) -> tuple[float, tuple[int, int, int]]:
    """Baseline: stream and record with no window; returns (cpu seconds, losses)."""
    emulator = EmulatorProcess()
    try:
        rig = Rig(emulator.port, folder / "baseline.h5")
        cpu0 = time.process_time()
        rig.start()
        time.sleep(seconds)
        result = rig.stop()
        return time.process_time() - cpu0, result
    finally:
        emulator.close()


def run_with_gui(seconds: float, folder: Path, view: str) -> dict:
    from PySide6.QtCore import QTimer
    from PySide6.QtWidgets import QApplication

    from gui.app import GIL_SWITCH_INTERVAL_S, VIEW_NAMES, MainWindow, frames_per_second
    from gui.live_data import LiveData
    from gui.worker import Session

    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)  # as `impact-rig gui` does
    app = QApplication.instance() or QApplication([])
    window = MainWindow()
    window.resize(1280, 800)
    window.show()
    emulator = EmulatorProcess()
    rig = Rig(emulator.port, folder / "with_gui.h5")
    session = Session()
    session.engine = rig.engine
    session.view = rig.engine.subscribe("gui", max_items=4000)
    session.sample_rate_hz = rig.board.sample_rate_hz
    window.session = session
    window.data = LiveData(session.sample_rate_hz)
    latencies: list[float] = []
    fps_samples: list[float] = []
    views = [v for v in VIEW_NAMES if v != "analysis"] if view == "cycle" else [view]

    def probe() -> None:
        posted = time.perf_counter()
        QTimer.singleShot(0, lambda: latencies.append(time.perf_counter() - posted))

    prober = QTimer()
    prober.timeout.connect(probe)
    prober.start(50)
    state = {"view": 0, "t0": 0.0}

    def every_second() -> None:
        fps_samples.append(frames_per_second(window, 1.0))
        elapsed = time.perf_counter() - state["t0"]
        window.show_view(views[int(elapsed // VIEW_PERIOD_S) % len(views)])

    sampler = QTimer()
    sampler.timeout.connect(every_second)
    sampler.start(1000)
    QTimer.singleShot(round(seconds * 1000), app.quit)
    cpu0 = time.process_time()
    state["t0"] = time.perf_counter()
    window.frame_times.clear()
    rig.start()
    app.exec()
    cpu = time.process_time() - cpu0
    intervals = window.frame_intervals_s()
    stats = rig.engine.stats()
    view_dropped = sum(s.dropped_samples for s in stats.subscribers if s.name == "gui")
    received, lost, file_lost = rig.stop()
    window.session = None
    window.shutdown()
    window.close()
    emulator.close()
    return {
        "cpu": cpu,
        "received": received,
        "lost": lost,
        "file_lost": file_lost,
        "view_dropped": view_dropped,
        "fps": fps_samples[1:] or fps_samples,  # the first second includes start-up
        "intervals": intervals,
        "latencies": latencies,
        "frames": window.frames,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="run length (full run: 60)")
    parser.add_argument(
        "--view",
        default="cycle",
        choices=("cycle", "time", "spectrum", "poincare", "phase"),
        help="the view in front (cycle: each for 5 s in turn)",
    )
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/gui.json")
    args = parser.parse_args(argv)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench-gui-") as tmp:
        folder = Path(tmp)
        print(f"4 x {RATE_HZ:,.0f} Hz + tach, recording to HDF5, {args.seconds:g} s, "
              f"view: {args.view}, {os.cpu_count()} CPUs")  # fmt: skip
        gui = run_with_gui(args.seconds, folder, args.view)
        base_cpu, (base_received, base_lost, base_file_lost) = run_without_gui(args.seconds, folder)
    fps = gui["fps"]
    ms = [1e3 * x for x in gui["intervals"]]
    lat = [1e3 * x for x in gui["latencies"]]
    print(
        f"frames: {gui['frames']} drawn, {statistics.mean(fps):.1f} fps mean, "
        f"{min(fps):.1f} fps worst second"
    )
    print(
        f"frame interval (nominal 33 ms): p50 {percentile(ms, 0.5):.1f} ms, "
        f"p99 {percentile(ms, 0.99):.1f} ms, max {max(ms):.1f} ms"
    )
    print(
        f"event-loop latency: p50 {percentile(lat, 0.5):.2f} ms, p99 {percentile(lat, 0.99):.2f} "
        f"ms, max {max(lat):.2f} ms ({len(lat)} probes)"
    )
    print(
        f"with GUI: {gui['received']:,} samples/channel, lost {gui['lost']} (engine), "
        f"{gui['file_lost']} (file); display skipped {gui['view_dropped']:,} samples"
    )
    print(
        f"without GUI (baseline): {base_received:,} samples/channel, lost {base_lost} (engine), "
        f"{base_file_lost} (file)"
    )
    print(
        f"CPU: {gui['cpu'] / args.seconds:.2f} s/s with GUI, {base_cpu / args.seconds:.2f} s/s "
        f"without; ratio {gui['cpu'] / max(base_cpu, 1e-9):.2f}x"
    )
    met = gui["lost"] == 0 and gui["file_lost"] == 0 and statistics.mean(fps) >= GOAL_FPS
    print(f"goal (0 lost, >= {GOAL_FPS:g} fps): {'met' if met else 'NOT met'}")
    if args.save:
        view = "" if args.view == "cycle" else f" ({args.view} view)"
        save(result("gui", [
            figure(f"GUI while streaming 4 x {RATE_HZ / 1e3:.0f} kHz and recording, "
                   f"{args.seconds:g} s{view}: frame rate", f"{statistics.mean(fps):.1f} fps mean"),
            figure("event-loop latency",
                   f"p50 {percentile(lat, 0.5):.2f} ms, p99 {percentile(lat, 0.99):.0f} ms"),
            figure("samples lost", f"{gui['lost']:,}" if gui["file_lost"] == gui["lost"] == 0
                   else f"{gui['lost']:,} (engine), {gui['file_lost']:,} (file)"),
        ], load_at_start=load))
    return 0


if __name__ == "__main__":
    sys.exit(main())
