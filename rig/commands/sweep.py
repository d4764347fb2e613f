"""``impact-rig sweep``: forced-response sweep (frequency or amplitude, up then down), recorded."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from analysis import quantities as q
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

With --plan FILE the steps are a plan's instead (a TOML file that 'impact-rig suggest'
writes, or one written by hand: [[step]] tables of frequency_hz, amplitude_m, settle_s and
dwell_s), run in the file's order, each with its own settle and dwell; they are marked as
a sweep's are, with direction 0 (neither up nor down).

Every step is checked against the rig file's safety limits before the shaker moves; a
plan's step outside them is refused, naming the step.
On Ctrl-C or any error the shaker ramps to zero and the file is closed valid (the
interrupted step is marked incomplete).
"""

EPILOG = """\
examples:
  impact-rig sweep --sim --sweep frequency --start 8 --stop 12 --steps 5 --beta 0.03 \\
      --settle 3 --dwell 10 --out fsweep.h5
  impact-rig sweep --sim --sweep amplitude --start 0.5 --stop 3 --steps 6 --drive-hz 10 \\
      --out asweep.h5
  impact-rig sweep --sim --plan next.toml --out next.h5
"""


DEFAULT_STEPS = 5
DEFAULT_SETTLE_S = 3.0
DEFAULT_DWELL_S = 5.0


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
    what = plan.add_mutually_exclusive_group(required=True)
    what.add_argument("--sweep", choices=("frequency", "amplitude"), help="what is stepped")
    what.add_argument(
        "--plan", type=Path, metavar="FILE",
        help="run a plan's steps instead (TOML, as 'impact-rig suggest' writes)",
    )
    plan.add_argument(
        "--start",
        type=float,
        help="first value (Hz for frequency, mm for amplitude); needed with --sweep",
    )
    plan.add_argument(
        "--stop", type=float, help="last value on the way up; needed with --sweep"
    )
    plan.add_argument("--steps", type=int, help="values on the way up (default 5)")
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
        metavar="SECONDS",
        help="settle time per step (default 3)",
    )
    plan.add_argument(
        "--dwell",
        type=float,
        metavar="SECONDS",
        help="steady-state data per step (default 5)",
    )
    plan.add_argument("--up-only", action="store_true", help="do not come back down")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Build the plan, check it against the limits, open the rig and sweep."""
    from rig.procedures import SweepPlan, run_sweep

    if args.plan is not None:
        return _run_plan(args)
    if args.start is None or args.stop is None:
        raise CommandError("--sweep needs --start and --stop")
    steps = DEFAULT_STEPS if args.steps is None else args.steps
    if steps < 1:
        raise CommandError(f"--steps is {steps}; expected at least 1")
    config = load_rig_config(args)
    values = np.linspace(args.start, args.stop, steps)
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
            settle_s=DEFAULT_SETTLE_S if args.settle is None else args.settle,
            dwell_s=DEFAULT_DWELL_S if args.dwell is None else args.dwell,
            down=not args.up_only,
        )
    except ValueError as error:
        raise CommandError(str(error)) from None
    check_drive_limits(config, [(f, a) for _, f, a in plan.steps()])
    record_and_report(args, config, args.fs, run_sweep, plan)
    return 0


# the options of a --sweep that a plan's steps take the place of
SWEEP_ONLY = ("start", "stop", "steps", "drive_hz", q.beta, "amplitude_mm", "settle", "dwell",
              "up_only")


def _run_plan(args: argparse.Namespace) -> int:
    """Run the plan file's steps: every one checked against the limits (the step named)
    before the rig is opened."""
    from analysis.experiment_plan import PlanFileError, read_plan
    from drivers.interfaces import LimitError
    from rig.procedures import check_drives, run_sweep

    given = [name for name in SWEEP_ONLY if getattr(args, name) not in (None, False)]
    if given:
        raise CommandError(f"--plan {args.plan}: the plan's steps set the drive; drop "
                           + ", ".join("--" + name.replace("_", "-") for name in given))
    try:
        plan = read_plan(args.plan)
    except PlanFileError as error:
        raise CommandError(str(error)) from None
    config = load_rig_config(args)
    for number, step in enumerate(plan.steps, start=1):
        try:
            check_drives(config.limits, config.source, [(step.frequency_hz, step.amplitude_m)])
        except LimitError as error:
            raise CommandError(f"{args.plan}: step {number} ({step.frequency_hz:g} Hz, "
                               f"{step.amplitude_m * 1e3:g} mm): {error}") from None
    record_and_report(args, config, args.fs, run_sweep, plan)
    return 0
