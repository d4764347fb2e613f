"""``impact-rig record``: headless logging of the rig (real or virtual) to a crash-safe HDF5."""

from __future__ import annotations

import argparse

from analysis.experiments import NAMES
from rig.cli import CommandError, add_command
from rig.commands.rig_options import (
    add_rig_options,
    check_drive_limits,
    drive_amplitude_m,
    load_rig_config,
    record_and_report,
)

IMPACT_DECAY_FS_HZ = 20_000.0

DESCRIPTION = """\
Record the rig to an HDF5 file (layout: docs/recording_layout.md). The file is
flushed every 0.5 s and readable while it is written; if the program is killed it
keeps everything up to the last flush. An existing file is never overwritten
without --overwrite. On Ctrl-C or any error the shaker ramps to zero and the file
is closed with the reason it stopped.

The experiment decides what happens:
  forced        drive the table at --drive-hz with amplitude --beta (A = beta L) or
                --amplitude-mm, let it settle, then record --duration seconds
  free_decay    barrier removed; the pendulum is held at --release-deg and let go
                (on the virtual rig by the simulation, on a real rig by you); the
                file starts --pretrigger seconds before it moved and ends when the
                swing is below --stop-below-rad or after --duration seconds
  impact_decay  the same with the barrier in place, at a high sample rate
                (default 20 kHz unless --fs is given)
Without --experiment: forced when --drive-hz is given, else free_decay.
"""

EPILOG = """\
examples:
  impact-rig record --sim --duration 10 --out run.h5
  impact-rig record --sim --experiment forced --drive-hz 10 --beta 0.03 --duration 30 \\
      --notes "case d" --out forced.h5
  impact-rig record --sim --experiment impact_decay --release-deg -20 --out impacts.h5
  impact-rig record --config lab.toml --experiment free_decay --out decay.h5
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``record`` sub-command."""
    parser = add_command(
        subparsers,
        "record",
        "record the rig (real or --sim) to a crash-safe HDF5 file",
        DESCRIPTION,
        EPILOG,
    )
    add_rig_options(parser)
    run_group = parser.add_argument_group("experiment")
    run_group.add_argument("--experiment", choices=NAMES, help="what to run (see above)")
    run_group.add_argument(
        "--duration",
        type=float,
        default=10.0,
        metavar="SECONDS",
        help="recording length (forced), or the longest a decay may last (default 10)",
    )
    run_group.add_argument("--drive-hz", type=float, metavar="HZ", help="drive frequency")
    amplitude = run_group.add_mutually_exclusive_group()
    amplitude.add_argument(
        "--beta", type=float, help="drive amplitude as a fraction of L (A = beta L, docs/MODEL.md)"
    )
    amplitude.add_argument("--amplitude-mm", type=float, help="drive amplitude in mm")
    run_group.add_argument(
        "--settle",
        type=float,
        default=2.0,
        metavar="SECONDS",
        help="forced: time for the drive to settle before recording (default 2)",
    )
    run_group.add_argument(
        "--release-deg",
        type=float,
        metavar="DEG",
        help="decays: where the pendulum is let go (default: the rig file's "
        "virtual.release_angle_rad; negative is away from the barrier)",
    )
    run_group.add_argument(
        "--pretrigger",
        type=float,
        default=0.5,
        metavar="SECONDS",
        help="decays: data kept from before the release (default 0.5)",
    )
    run_group.add_argument(
        "--stop-below-rad",
        type=float,
        default=0.005,
        metavar="RAD",
        help="decays: stop when half the peak-to-peak swing over 1 s is below this (default 0.005)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Validate everything, open the rig, run the procedure, print a summary."""
    import math

    from analysis.experiments import FORCED, FREE_DECAY, IMPACT_DECAY, experiment_kind
    from rig.procedures import DecayPlan, TimedPlan, record_decay, record_timed

    experiment = args.experiment or (FORCED if args.drive_hz is not None else FREE_DECAY).name
    kind = experiment_kind(experiment)
    if args.duration is None or not args.duration > 0:
        raise CommandError(f"--duration is {args.duration}; expected a positive number of seconds")
    for option, seconds in (("--settle", args.settle), ("--pretrigger", args.pretrigger)):
        if not (math.isfinite(seconds) and seconds >= 0):
            raise CommandError(f"{option} is {seconds}; expected a number of seconds >= 0")
    config = load_rig_config(args)
    if kind.driven:
        if args.drive_hz is None or (args.beta is None and args.amplitude_mm is None):
            raise CommandError("a forced recording needs --drive-hz and --beta (or --amplitude-mm)")
        amplitude_m = drive_amplitude_m(args, config)
        check_drive_limits(config, [(args.drive_hz, amplitude_m)])
        plan = TimedPlan(experiment, args.duration, args.drive_hz, amplitude_m, args.settle)
        procedure = record_timed
    else:
        for option, value in (
            ("--drive-hz", args.drive_hz),
            ("--beta", args.beta),
            ("--amplitude-mm", args.amplitude_mm),
        ):
            if value is not None:
                raise CommandError(f"{option} makes no sense for a {experiment} (no drive)")
        release = (
            math.radians(args.release_deg)
            if args.release_deg is not None
            else config.virtual.release_angle_rad
        )
        plan = DecayPlan(
            experiment=experiment,
            release_angle_rad=release,
            pretrigger_s=args.pretrigger,
            stop_below_rad=args.stop_below_rad,
            max_duration_s=args.duration,
        )
        procedure = record_decay
    fs = args.fs
    if fs is None and kind is IMPACT_DECAY:
        fs = IMPACT_DECAY_FS_HZ
    record_and_report(args, config, fs, procedure, plan)
    return 0
