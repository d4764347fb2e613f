"""``impact-rig sweep``: forced-response sweep (frequency or amplitude, up then down), recorded."""

from __future__ import annotations

import argparse

import numpy as np

from rig.cli import CommandError, add_command
from rig.commands.rig_options import (
    add_rig_options,
    check_drive_limits,
    drive_amplitude_m,
    load_rig_config,
    record_and_report,
)

DESCRIPTION = """\
Step the shaker's frequency (at a fixed amplitude) or its amplitude (at a fixed
frequency) from --start to --stop in --steps equal steps, then back down (unless
--up-only). At each step the drive settles for --settle seconds, then the data of
the next --dwell seconds are the step's steady state. Every step is marked in the
recording (/sweep_steps: its setting, where it settled and where its dwell lies),
so 'impact-rig export --per-step' can cut the file into one record per step.

Every step is checked against the rig file's safety limits before the shaker moves.
On Ctrl-C or any error the shaker ramps to zero and the file is closed valid (the
interrupted step is marked incomplete).
"""

EPILOG = """\
examples:
  impact-rig sweep --sim --sweep frequency --start 8 --stop 12 --steps 5 --beta 0.03 \\
      --settle 3 --dwell 10 --out fsweep.h5
  impact-rig sweep --sim --sweep amplitude --start 0.5 --stop 3 --steps 6 --drive-hz 10 \\
      --out asweep.h5
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` sub-command."""
    parser = add_command(
        subparsers,
        "sweep",
        "forced-response sweep of frequency or amplitude, up and down, recorded",
        DESCRIPTION,
        EPILOG,
    )
    add_rig_options(parser)
    plan = parser.add_argument_group("sweep")
    plan.add_argument(
        "--sweep", choices=("frequency", "amplitude"), required=True, help="what is stepped"
    )
    plan.add_argument(
        "--start",
        type=float,
        required=True,
        help="first value (Hz for frequency, mm for amplitude)",
    )
    plan.add_argument("--stop", type=float, required=True, help="last value on the way up")
    plan.add_argument("--steps", type=int, default=5, help="values on the way up (default 5)")
    plan.add_argument(
        "--drive-hz", type=float, metavar="HZ", help="the fixed frequency of an amplitude sweep"
    )
    fixed = plan.add_mutually_exclusive_group()
    fixed.add_argument(
        "--beta", type=float, help="the fixed amplitude of a frequency sweep, as A = beta L"
    )
    fixed.add_argument(
        "--amplitude-mm", type=float, help="the fixed amplitude of a frequency sweep, in mm"
    )
    plan.add_argument(
        "--settle",
        type=float,
        default=3.0,
        metavar="SECONDS",
        help="settle time per step (default 3)",
    )
    plan.add_argument(
        "--dwell",
        type=float,
        default=5.0,
        metavar="SECONDS",
        help="steady-state data per step (default 5)",
    )
    plan.add_argument("--up-only", action="store_true", help="do not come back down")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build the plan, check it against the limits, open the rig and sweep."""
    from rig.procedures import SweepPlan, run_sweep

    if args.steps < 1:
        raise CommandError(f"--steps is {args.steps}; expected at least 1")
    config = load_rig_config(args)
    values = np.linspace(args.start, args.stop, args.steps)
    if args.sweep == "frequency":
        if args.beta is None and args.amplitude_mm is None:
            raise CommandError(
                "a frequency sweep needs its fixed amplitude: --beta or --amplitude-mm"
            )
        fixed = drive_amplitude_m(args, config)
    else:
        if args.drive_hz is None:
            raise CommandError("an amplitude sweep needs its fixed frequency: --drive-hz")
        fixed = args.drive_hz
        values = values * 1e-3
    try:
        plan = SweepPlan(
            args.sweep,
            tuple(float(v) for v in values),
            float(fixed),
            settle_s=args.settle,
            dwell_s=args.dwell,
            down=not args.up_only,
        )
    except ValueError as error:
        raise CommandError(str(error)) from None
    check_drive_limits(config, [(f, a) for _, f, a in plan.steps()])
    record_and_report(args, config, args.fs, run_sweep, plan)
    return 0
