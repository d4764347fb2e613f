"""A long recording from the virtual rig with faults injected: what it lost, grew and wrote.

The virtual rig runs in its own process (``python -m harness.soak --serve LINK RATE``):
the DAQ board emulator on a pty reached through a stable path (``LINK``, a symlink as
udev's ``/dev/serial/by-id`` links are) and the amplifier's controller on Modbus TCP.
Lines on its stdin inject faults: ``garble N`` (random bytes before a frame and the CRC
of the next N frames flipped), ``unplug S`` (the board's pty closes; S seconds later a
freshly reset board serves a new pty at the same path), ``amplifier S`` (the amplifier's
Modbus server goes away for S seconds) and ``log`` (every board's fault log, as JSON).

This process runs what a lab PC runs: the serial driver with its reconnection, the role
drivers, the acquisition engine, the HDF5 recorder and the Modbus shaker driver (its
link polled as a drive monitor does; after a restart the drive is commanded again).
:func:`run_soak` records for the time asked, one fault every ``fault_every_s`` in turn,
then reads the file and returns :class:`SoakFigures`: resident memory after warm-up and
at the end, samples lost outside the fault windows, the windows the file holds, stored
samples that repeat an index, and whether a reader in another process, ``impact-rig
export`` and h5py read it.  ``benchmarks/soak.py`` prints them for an hour's run;
``tests/daq/test_soak.py`` checks them on seconds.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

if TYPE_CHECKING:
    from analysis.progress import ProgressText

ROOT = Path(__file__).resolve().parents[1]
FAULT_KINDS = ("garbled", "unplug", "amplifier")
GARBLED_FRAMES = 3  # frames whose CRC is flipped by one "garbled" fault
AWAY_S = 1.0  # how long an unplugged board or a restarting amplifier stays away
INJECTED = ("corrupt_crc", "dropped_bytes")  # board log kinds the soak asked for
DRIVE_HZ, DRIVE_M = 2.0, 0.001  # the drive kept on through the run


# -- the rig's side: its own process --------------------------------------------------------


def _point(link: Path, port: str) -> None:
    tmp = link.with_name(link.name + ".new")
    tmp.unlink(missing_ok=True)
    tmp.symlink_to(port)
    tmp.replace(link)


def serve(link: Path, rate_hz: float) -> int:
    """Run the virtual rig, the DAQ board behind ``link``; act on stdin lines until ``quit``."""
    from rig.config import load_config
    from rig.devices import _start_virtual_rig

    sim = _start_virtual_rig(load_config(), rate_hz, 1.0)
    boards = [sim.daq]
    _point(link, sim.daq.port)
    print(f"modbus: {sim.amplifier.port}", flush=True)
    print("ready", flush=True)
    try:
        for line in sys.stdin:
            words = line.split()
            if not words:
                continue
            verb = words[0]
            if verb == "garble":
                sim.daq.faults.inject_garbage(64)
                sim.daq.faults.corrupt_crc(frames=int(words[1]))
            elif verb == "unplug":
                link.unlink(missing_ok=True)
                _point(link, sim.replug_daq(float(words[1])))
                boards.append(sim.daq)
            elif verb == "amplifier":
                sim.restart_amplifier(float(words[1]))
            elif verb == "log":
                logs = [[asdict(record) for record in board.faults.log] for board in boards]
                print(json.dumps(logs), flush=True)
                continue
            elif verb == "quit":
                break
            print(f"ok {verb}", flush=True)
    finally:
        sim.stop()
    return 0


class RigProcess:
    """The virtual rig in its own process, faults asked for on its stdin."""

    def __init__(self, link: Path, rate_hz: float) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "harness.soak", "--serve", str(link), repr(rate_hz)],
            cwd=ROOT,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            env={**os.environ, "PYTHONPATH": str(ROOT)},
        )
        self.modbus_port = int(self._line().split(": ")[1])
        if self._line() != "ready":
            raise RuntimeError("the virtual rig did not start")

    def _line(self) -> str:
        assert self.process.stdout is not None
        line = self.process.stdout.readline()
        if not line:
            raise RuntimeError(f"the virtual rig ended (exit {self.process.wait(10)})")
        return line.strip()

    def ask(self, command: str) -> str:
        assert self.process.stdin is not None
        self.process.stdin.write(command + "\n")
        self.process.stdin.flush()
        return self._line()

    def close(self) -> None:
        if self.process.poll() is None:
            assert self.process.stdin is not None
            with contextlib.suppress(OSError):
                self.process.stdin.write("quit\n")
                self.process.stdin.close()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(10)


# -- the host's side -----------------------------------------------------------------------


@dataclass
class SoakFigures:
    """What a soak run measured (JSON-ready)."""

    seconds: float
    sample_rate_hz: float
    fault_every_s: float
    faults: list[tuple[float, str]] = field(default_factory=list)  # (host time, kind)
    samples_stored: int = 0
    samples_lost: int = 0
    samples_lost_in_fault_windows: int = 0
    samples_lost_outside_fault_windows: int = 0
    lost_outside_by_board_log: dict[str, int] = field(default_factory=dict)
    injected_windows: int = 0
    injected_windows_in_file: int = 0  # a gap holds every sample of the window
    unplugs: int = 0
    outages_in_file: int = 0  # /outages rows of the angle channel
    gaps_table_matches_blocks: bool = False
    duplicated_samples: int = 0
    amplifier_restarts: int = 0
    amplifier_windows: list[tuple[float, float]] = field(default_factory=list)
    drive_off_rows_in_file: int = 0  # commanded drive-off rows (one per amplifier loss)
    watch_error: str = ""  # anything but a DeviceError out of the shaker driver
    rss_warm_mb: float = 0.0
    rss_end_mb: float = 0.0
    rss_max_mb: float = 0.0
    rss_growth_pct: float = 0.0
    cpu_share_of_one_core: float = 0.0
    live_reads_ok: int = 0
    live_reads_failed: list[str] = field(default_factory=list)
    reader_ok: bool = False
    export_ok: bool = False
    export_message: str = ""
    h5py_ok: bool = False
    h5py_version: str = h5py.__version__
    file_bytes: int = 0


def resident_mb() -> float:
    """This process's resident memory (MB), from /proc."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


class AmplifierWatch:
    """Polls the amplifier as a drive monitor does; when the link is lost, notes the drive
    off in the recording; when the driver has it again, commands the drive once more."""

    def __init__(self, shaker, engine) -> None:
        self.shaker, self.engine = shaker, engine
        self.windows: list[tuple[float, float]] = []
        self.error: BaseException | None = None
        self._lost_at: float | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="amplifier-watch", daemon=True)

    def start(self) -> None:
        self._thread.start()

    @property
    def lost(self) -> bool:
        """The link was lost and the drive not yet commanded again."""
        return self._lost_at is not None

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(10)

    def drive(self) -> None:
        self.shaker.frequency_hz = DRIVE_HZ
        self.shaker.amplitude_m = DRIVE_M
        self.shaker.enabled = True
        self.engine.note_drive(DRIVE_HZ, DRIVE_M, True)

    def _run(self) -> None:
        from drivers.interfaces import DeviceError

        while not self._stop.wait(0.25):
            try:
                if self._lost_at is None:
                    self.shaker.measured()
                elif self.shaker.connected and not self.shaker.reconnecting:
                    self.shaker.clear_faults()  # its watchdog tripped while the link was down
                    self.drive()
                    self.windows.append((self._lost_at, self.engine.host_time_s()))
                    self._lost_at = None
            except DeviceError:
                if self._lost_at is None:
                    self._lost_at = self.engine.host_time_s()
                    self.engine.note_drive(DRIVE_HZ, 0.0, False)
            except BaseException as error:
                self.error = error
                return


def _read_live(path: Path) -> str:
    """Open the file being written from another process: '' when it reads, else why not."""
    code = (
        "import sys\nfrom recording.reader import open_recording\n"
        "with open_recording(sys.argv[1]) as r:\n"
        "    n = len(r.complete_blocks('angle'))\n    r.status()\n"
        "print(n)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    if done.returncode != 0 or int(done.stdout.strip() or 0) <= 0:
        return (done.stderr.strip().splitlines() or ["no blocks"])[-1]
    return ""


def run_soak(
    folder: Path,
    seconds: float,
    *,
    fault_every_s: float = 60.0,
    rate_hz: float = 200_000.0,
    warmup_s: float | None = None,
    progress: ProgressText | None = None,
) -> SoakFigures:
    """Record for ``seconds`` with a fault every ``fault_every_s``; read the file; figures."""
    from drivers.daq import DaqBoard
    from drivers.modbus_shaker import ModbusTcpBackend
    from drivers.sensors import LaserDisplacementSensor, PotentiometerAngleSensor, Tachometer
    from drivers.serial_daq import SerialDaqBackend
    from drivers.shaker import ShakerAmplifier
    from rig.config import load_config
    from rig.engine import AcquisitionEngine
    from rig.recorder import ChannelSpec, Recorder, RecordingMetadata, attach_recorder

    say = progress or (lambda text: None)
    warmup_s = min(300.0, seconds / 6) if warmup_s is None else warmup_s
    config = load_config()
    link = folder / "ttyACM-soak"
    path = folder / "soak.h5"
    figures = SoakFigures(seconds, rate_hz, fault_every_s)
    rig = RigProcess(link, rate_hz)
    board = shaker = engine = writer = recorder = watch = None
    try:
        board = DaqBoard(
            SerialDaqBackend(str(link)),
            sample_rate_hz=rate_hz,
            analog_channels=(config.daq.angle_input, config.daq.table_input),
            reconnect_for_s=30.0,
            reconnect_interval_s=0.05,
        )
        angle = PotentiometerAngleSensor(board, config.daq.angle_input, config.angle_calibration)
        table = LaserDisplacementSensor(board, config.daq.table_input, config.table_calibration)
        tach = Tachometer(board, config.tach_calibration)
        engine = AcquisitionEngine([angle, table, tach])
        specs = [
            ChannelSpec("angle", "samples", "rad", rate_hz, "IRDAQ-4", None, "int16"),
            ChannelSpec("table", "samples", "m", rate_hz, "IRDAQ-4", None, "int16"),
            ChannelSpec("tach", "pulses", "", rate_hz, "IRDAQ-4", None),
        ]
        recorder = Recorder(path, specs, RecordingMetadata("forced", notes="soak"))
        writer = attach_recorder(engine, recorder)
        shaker = ShakerAmplifier(
            ModbusTcpBackend("127.0.0.1", rig.modbus_port, timeout_s=0.3, retries=0),
            config.limits,
            watchdog_s=config.watchdog_s,
            reconnect=True,
        ).connect()
        shaker.ramp_rate_m_s = 0.01
        board.start_roles(angle, table, tach)
        engine.start()
        watch = AmplifierWatch(shaker, engine)
        watch.drive()
        watch.start()
        _record(rig, engine, recorder, writer, watch, path, figures, warmup_s, say)
        watch.stop()
        if watch.error is not None:  # a miss to report with the rest, not a lost run
            figures.watch_error = repr(watch.error)
        figures.amplifier_windows = [(round(a, 3), round(b, 3)) for a, b in watch.windows]
    finally:
        if watch is not None:
            watch.stop()
        if engine is not None:
            engine.stop()
        if writer is not None:
            writer.finish()
        if recorder is not None:
            recorder.close()
        if shaker is not None:
            with contextlib.suppress(Exception):
                shaker.close()
        if board is not None:
            with contextlib.suppress(Exception):
                board.close()
        logs = json.loads(rig.ask("log")) if rig.process.poll() is None else []
        rig.close()
    _check_file(path, logs, figures, folder)
    return figures


def _record(rig, engine, recorder, writer, watch, path, figures, warmup_s, say) -> None:
    """The run itself: faults in turn, memory sampled, the file read while written."""
    every_s = figures.fault_every_s
    cpu0, wall0 = sum(os.times()[:2]), time.monotonic()
    rss: list[tuple[float, float]] = []
    next_fault, next_read, turn = every_s, every_s / 2, 0
    reading: threading.Thread | None = None

    def read_live(at_s: float) -> None:  # another process opens the file being written
        problem = _read_live(path)
        if problem:
            figures.live_reads_failed.append(f"{at_s:.0f} s: {problem}")
        else:
            figures.live_reads_ok += 1

    while (elapsed := time.monotonic() - wall0) < figures.seconds:
        if engine.error is not None:
            raise RuntimeError(f"the acquisition stopped: {engine.error}")
        if recorder.error is not None or writer.error is not None:
            raise RuntimeError(f"the recorder stopped: {recorder.error or writer.error}")
        if not rss or elapsed - rss[-1][0] >= 1.0:
            rss.append((elapsed, resident_mb()))
        if elapsed >= next_fault:
            kind = FAULT_KINDS[turn % len(FAULT_KINDS)]
            turn += 1
            figures.faults.append((round(engine.host_time_s(), 3), kind))
            rig.ask(
                {"garbled": f"garble {GARBLED_FRAMES}", "unplug": f"unplug {AWAY_S}",
                 "amplifier": f"amplifier {AWAY_S}"}[kind]
            )
            say(f"{elapsed:7.1f} s  {kind:9s} rss {rss[-1][1]:.1f} MB")
            next_fault += every_s
        if elapsed >= next_read and (reading is None or not reading.is_alive()):
            reading = threading.Thread(target=read_live, args=(elapsed,), daemon=True)
            reading.start()
            next_read += every_s
        time.sleep(0.1)
    # the last fault's devices back before the end (bounded: a miss shows in the figures)
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline and (
        watch.lost or engine.stats().reconnecting or (reading and reading.is_alive())
    ):
        time.sleep(0.1)
    wall = time.monotonic() - wall0
    figures.cpu_share_of_one_core = round((sum(os.times()[:2]) - cpu0) / wall, 3)
    warm = [mb for t, mb in rss if t >= warmup_s] or [rss[-1][1]]
    figures.rss_warm_mb, figures.rss_end_mb = round(warm[0], 1), round(rss[-1][1], 1)
    figures.rss_max_mb = round(max(warm), 1)
    figures.rss_growth_pct = round(100 * (figures.rss_end_mb / figures.rss_warm_mb - 1), 2)


def _intervals_minus(a: list[tuple[int, int]], b: list[tuple[int, int]]) -> int:
    """Samples in the union of intervals ``a`` ([start, stop)) not in the union of ``b``."""
    edges = sorted({x for s, e in a + b for x in (s, e)})
    if not edges:
        return 0
    points = np.array(edges, dtype=np.int64)
    mids = points[:-1]

    def covered(intervals: list[tuple[int, int]]) -> np.ndarray:
        inside = np.zeros(mids.size, bool)
        for s, e in intervals:
            inside |= (mids >= s) & (mids < e)
        return inside

    widths = np.diff(points)
    return int(widths[covered(a) & ~covered(b)].sum())


def _merged(intervals: list[tuple[int, int]]) -> list[tuple[int, int]]:
    out: list[tuple[int, int]] = []
    for s, e in sorted(intervals):
        if out and s <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], e))
        else:
            out.append((s, e))
    return out


def _check_file(path: Path, logs: list, figures: SoakFigures, folder: Path) -> None:
    from recording.reader import open_recording

    figures.file_bytes = path.stat().st_size
    with open_recording(path) as recording:
        recording.verify()
        blocks = recording.complete_blocks("angle")
        outages = recording.outages()
        drive = recording.drive_log()
        figures.reader_ok = True
    with h5py.File(path, "r") as raw:  # the file as any HDF5 reader sees it
        gaps = raw["channels/angle/gaps"][:]
        h5_blocks = raw["channels/angle/blocks"][:]
        figures.h5py_ok = bool(
            h5_blocks.shape[0] >= blocks.shape[0]
            and raw["channels/angle/raw"].shape[0] >= int(blocks["n_samples"].sum())
        )
    first, n = blocks["first_index"].astype(np.int64), blocks["n_samples"].astype(np.int64)
    figures.samples_stored = int(n.sum())
    figures.duplicated_samples = int(np.maximum(0, (first[:-1] + n[:-1]) - first[1:]).sum())
    lost = _merged(
        [(int(e), int(s)) for e, s in zip(first[:-1] + n[:-1], first[1:], strict=True) if s > e]
    )
    if first.size and first[0] > 0:
        lost = _merged([(0, int(first[0])), *lost])
    figures.samples_lost = sum(e - s for s, e in lost)
    table = _merged([(int(g["start_index"]), int(g["start_index"] + g["length"])) for g in gaps])
    end = int(first[-1] + n[-1]) if first.size else 0
    figures.gaps_table_matches_blocks = [w for w in table if w[0] < end] == lost
    angle_outages = sorted(
        (int(o["start_index"]), int(o["length"])) for o in outages if o["channel"] == b"angle"
    )
    figures.unplugs = sum(1 for _, kind in figures.faults if kind == "unplug")
    figures.amplifier_restarts = sum(1 for _, kind in figures.faults if kind == "amplifier")
    figures.outages_in_file = len(angle_outages)
    windows = [(s, s + length) for s, length in angle_outages]
    offsets = [0] + [s + length for s, length in angle_outages]
    injected: list[tuple[int, int]] = []
    outside: dict[str, int] = {}
    for k, log in enumerate(logs):
        offset = offsets[k] if k < len(offsets) else None
        for record in log:
            if record["n_samples"] == 0:
                continue
            if offset is None:  # a board whose outage the file lacks: its losses unexplained
                outside[record["kind"]] = outside.get(record["kind"], 0) + record["n_samples"]
                continue
            start = record["first_index"] + offset
            window = (start, start + record["n_samples"])
            if window[0] >= end:
                continue  # after the recording's last sample
            if record["kind"] in INJECTED:
                injected.append(window)
            else:
                outside[record["kind"]] = outside.get(record["kind"], 0) + record["n_samples"]
    figures.injected_windows = len(injected)
    figures.injected_windows_in_file = sum(
        1 for w in injected if _intervals_minus([w], lost) == 0
    )
    fault_windows = injected + windows
    figures.samples_lost_outside_fault_windows = _intervals_minus(lost, fault_windows)
    figures.samples_lost_in_fault_windows = (
        figures.samples_lost - figures.samples_lost_outside_fault_windows
    )
    figures.lost_outside_by_board_log = outside
    commanded = drive[drive["source"] == 0] if "source" in drive.dtype.names else drive
    figures.drive_off_rows_in_file = int(np.sum(commanded["enabled"] == 0))
    csv = folder / "soak.csv"
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", "export", str(path), "--out", str(csv),
         "--gaps", "longest", "--overwrite"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=3600,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    figures.export_message = (done.stderr.strip().splitlines() or [""])[-1]
    if done.returncode == 0 and csv.exists():
        with csv.open(encoding="utf-8") as text:
            header = text.readline()
            rows = sum(1 for _ in text)
        figures.export_ok = header.startswith("time_s") and rows > 0
        csv.unlink()


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--serve":
        sys.exit(serve(Path(sys.argv[2]), float(sys.argv[3])))
    sys.exit("usage: python -m harness.soak --serve LINK RATE_HZ (benchmarks/soak.py runs it)")
