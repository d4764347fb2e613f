"""Options shared by the commands that run the rig (record, sweep): where, how fast, into what.

``--config FILE`` names a rig file (default: the shipped virtual rig); ``--sim`` runs
the same configuration on the virtual rig over its real protocols (pty serial DAQ +
Modbus TCP amplifier, started in this process).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rig.cli import CommandError

if TYPE_CHECKING:  # imported lazily at run time: a fast --help
    from rig.config import RigConfig
    from rig.devices import RigDevices
    from rig.procedures import ProcedureResult


CONFIG_HELP = (
    "rig file (TOML): devices and ports, calibrations, safety limits, rig constants "
    "(default: the shipped rig/default_rig.toml, which is the virtual rig)"
)


def sample_rate(text: str) -> float:
    """--fs as a positive, finite number of Hz (argparse names the option on refusal)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of Hz") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a positive sample rate in Hz")
    return value


def add_rig_options(parser: argparse.ArgumentParser) -> None:
    """--config, --sim, --fs, --out, --overwrite, --notes."""
    group = parser.add_argument_group("rig")
    group.add_argument("--config", metavar="FILE", help=CONFIG_HELP)
    group.add_argument(
        "--sim",
        action="store_true",
        help="run on the virtual rig (its emulators on a pty and loopback Modbus TCP, "
        "reached by the real drivers), whatever the rig file says",
    )
    group.add_argument(
        "--fs",
        type=sample_rate,
        metavar="HZ",
        help="DAQ sample rate in Hz (default: the rig file's daq.sample_rate_hz)",
    )
    out = parser.add_argument_group("output")
    out.add_argument("--out", required=True, metavar="FILE.h5", help="the HDF5 recording to write")
    out.add_argument(
        "--overwrite",
        action="store_true",
        help="replace FILE.h5 if it exists (without it an existing recording is never touched)",
    )
    out.add_argument("--notes", default="", help="operator notes kept in the recording")
    out.add_argument(
        "--compression",
        choices=("auto", "gzip", "lzf", "none"),
        default="auto",
        help="HDF5 compression: auto = gzip level 1 (any HDF5 tool reads it) up to 50 kHz, "
        "lzf (less CPU, h5py) above; none = least CPU, about twice the bytes (default auto)",
    )


def compression(args: argparse.Namespace) -> str | None:
    """The recorder's compression argument from --compression."""
    return None if args.compression == "none" else args.compression


def load_rig_config(args: argparse.Namespace) -> RigConfig:
    """The validated rig configuration the options ask for (CommandError on a bad file)."""
    from rig.config import ConfigError, load_config
    from rig.devices import virtual_config

    try:
        config = load_config(args.config)
    except ConfigError as error:
        raise CommandError(str(error)) from None
    return virtual_config(config) if args.sim else config


def check_output(args: argparse.Namespace) -> Path:
    """Refuse an output (or the log beside it) that exists or cannot be written, before any
    device is touched; with --config, the rig file is an input never written over."""
    from analysis.output_paths import HDF5_SUFFIXES, check_outputs, check_suffix
    from rig.logs import log_path_for
    from rig.recorder import RecordingError, check_destination

    inputs = [Path(args.config)] if args.config else []
    check_suffix(args.out, HDF5_SUFFIXES, "a recording (HDF5)")  # a name to put its log beside
    check_outputs([Path(args.out), log_path_for(args.out)], inputs=inputs, overwrite=args.overwrite)
    try:
        return check_destination(Path(args.out), overwrite=args.overwrite)
    except RecordingError as error:
        raise CommandError(str(error)) from None


def open_devices(config: RigConfig, fs: float | None) -> RigDevices:
    """Open the rig (CommandError naming the device when it cannot be reached)."""
    from drivers.interfaces import DeviceError, LimitError
    from rig.devices import open_rig
    from rig.logs import progress

    where = "the virtual rig" if config.is_virtual else config.source
    progress(f"opening the devices of {where} ...")
    try:
        return open_rig(config, sample_rate_hz=fs)
    except (DeviceError, LimitError, OSError) as error:
        raise CommandError(f"cannot open the rig ({config.source}): {error}") from None


def check_drive_limits(config: RigConfig, settings: Iterable[tuple[float, float]]) -> None:
    """CommandError naming the rig file for any (frequency_hz, amplitude_m) its limits forbid,
    before any device is opened (the procedure checks the same way again once they are)."""
    from drivers.interfaces import LimitError
    from rig.procedures import check_drives

    try:
        check_drives(config.limits, config.source, settings)
    except LimitError as error:
        raise CommandError(str(error)) from None


def run_procedure(
    config: RigConfig,
    fs: float | None,
    path: Path,
    procedure: Callable[[RigDevices], ProcedureResult],
) -> ProcedureResult:
    """Open the rig, run ``procedure(devices)``, close the rig; its result.

    A device, recording or acquisition failure becomes a CommandError that says the drive
    went to zero and the file keeps what was recorded (the procedure saw to both).  Every
    log record of the run goes to RUN.log beside the recording.
    """
    from rig.logs import FILE_ONLY, log, log_file, log_path_for, log_provenance

    with log_file(log_path_for(path)) as logging_to:
        log.info("impact-rig run of %s into %s (this log: %s)", config.source, path, logging_to)
        log_provenance()
        try:
            result = _run_on_devices(config, fs, path, procedure)
        except CommandError as error:
            log.error("%s", error, extra=FILE_ONLY)  # main() prints it
            raise
        log.info("%s: %s", path, result.stop_reason)
        return result


def _run_on_devices(
    config: RigConfig,
    fs: float | None,
    path: Path,
    procedure: Callable[[RigDevices], ProcedureResult],
) -> ProcedureResult:
    from rig.procedures import RIG_FAILURES

    devices = open_devices(config, fs)
    try:
        return procedure(devices)
    except RIG_FAILURES as error:
        raise CommandError(
            f"{error} (the drive was ramped to zero; {path} keeps the data recorded so far)"
        ) from None
    finally:
        devices.close()


def record_and_report(
    args: argparse.Namespace,
    config: RigConfig,
    fs: float | None,
    procedure: Callable[..., ProcedureResult],
    plan: Any,
) -> None:
    """Run ``procedure(devices, path, plan, ...)`` (a rig.procedures recording) into the
    checked --out with --notes, --overwrite and the compression, and print its summary."""
    path = check_output(args)
    result = run_procedure(
        config,
        fs,
        path,
        lambda devices: procedure(
            devices,
            path,
            plan,
            notes=args.notes,
            overwrite=args.overwrite,
            compression=compression(args),
            progress=ProgressLine(),
        ),
    )
    report(result)


def drive_amplitude_m(args: argparse.Namespace, config: RigConfig) -> float:
    """The drive amplitude given as --beta (A = beta L of the rig) or --amplitude-mm."""
    return args.beta * config.constants.L_m if args.beta is not None else args.amplitude_mm * 1e-3


class ProgressLine:
    """Progress of a run (rig.logs.progress): every new kind of message, repeats of one kind
    at most once a second (the log file beside the recording keeps them all)."""

    def __init__(self) -> None:
        self._last = 0.0
        self._kind = ""

    def __call__(self, text: str) -> None:
        from rig.logs import progress

        now = time.monotonic()
        kind = text.split(":", 1)[0]
        if kind == self._kind and now - self._last < 1.0:
            return
        self._last, self._kind = now, kind
        progress(text)


def report(result: ProcedureResult) -> None:
    """One summary line on stdout."""
    print(
        f"{result.path}: {result.experiment}, {result.samples_written} samples written "
        "(all channels), "
        f"{result.samples_lost} lost ("
        + ", ".join(f"{name} {lost}" for name, lost in result.lost_per_stream.items())
        + f"), {result.duration_s:.1f} s"
        + (f", {result.steps} sweep steps" if result.steps else "")
        + f" ({result.stop_reason})"
    )
