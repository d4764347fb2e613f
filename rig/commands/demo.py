"""``impact-rig demo``: the whole product in minutes, on the virtual rig over its real protocols."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

from rig.cli import CommandError, add_command
from rig.logs import progress

if TYPE_CHECKING:  # the demo is imported when it runs: a fast --help
    from rig.demo.settings import HiddenCause

DEFAULT_OUT = "impact-rig-demo"

DESCRIPTION = """\
Run the main job end to end on the virtual rig (its DAQ board on a pseudo-terminal,
its amplifier on Modbus TCP, reached by the same drivers a real rig uses), with a
physical effect switched on that the baseline model lacks:

  1. record a free decay, an impact decay and a forced amplitude sweep at 10 Hz
     (beta = A/L up, then down) to HDF5
  2. identify L, zeta (free decay) and K, mu0 (impact decay) with 95 % intervals
  3. run the discrepancy analysis on the records (it is not told the effect)
  4. judge the regime of every sweep step from its points sampled once per drive
     period on the tachometer (aware of the noise), and draw the measured bifurcation
     diagram against the one simulated with the identified model
  5. write a report folder: report.md and report.html with figures, the JSON reports
     (docs/MODEL.md sections 6 and 7) and the recordings; the effect is revealed there

Takes a few minutes on two cores.  --quick takes about a minute: smaller records and
simulations, no analysis of a single sweep step, and the impact decay and the sweep are
checked only for the cause the free decay showed (the full demo tries every candidate).
"""

EPILOG = """\
examples:
  impact-rig demo
  impact-rig demo --quick --out /tmp/demo
  impact-rig demo --cause sensor_offset --param offset_rad=0.004 --out offset-demo
  impact-rig demo --cause none --out baseline-demo       # the baseline model is exact
causes (docs/MODEL.md section 6): coulomb_friction, quadratic_drag, barrier_offset,
  contact_exponent, contact_damping_law, sensor_offset, sensor_nonlinearity,
  sensor_lag, excitation_distortion, excitation_amplitude, none
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``demo`` sub-command."""
    parser = add_command(
        subparsers,
        "demo",
        "the whole job on the virtual rig: record, identify, explain, report",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument(
        "--out",
        default=DEFAULT_OUT,
        metavar="DIR",
        help=f"report folder (default ./{DEFAULT_OUT}); a non-empty one is refused",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="write into a non-empty --out folder"
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="about a minute: smaller records and simulations; the impact decay and the "
        "sweep checked only for the cause the free decay showed",
    )
    parser.add_argument(
        "--cause",
        metavar="NAME",
        help="the effect the virtual rig hides (default: the one in the rig file's "
        "[virtual.causes], else coulomb_friction with Tc_N_m = 2e-5; 'none' for the "
        "baseline model alone)",
    )
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a parameter of --cause (repeatable), e.g. Tc_N_m=3e-5",
    )
    parser.add_argument(
        "--config",
        metavar="FILE",
        help="rig file whose constants and calibrations the virtual rig takes "
        "(default: the shipped rig/default_rig.toml); always run on the virtual rig",
    )
    parser.set_defaults(func=run)


def _parse_params(items: list[str]) -> dict[str, float]:
    values: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name.strip():
            raise CommandError(f"--param {item!r}: expected NAME=VALUE, e.g. Tc_N_m=2e-5")
        try:
            values[name.strip()] = float(text)
        except ValueError:
            raise CommandError(f"--param {item!r}: {text!r} is not a number") from None
    return values


def _cause_from_rig_file(config_path: str | None, params: dict[str, float]):
    """The cause the rig file's [virtual.causes] switches on (the default cause without one)."""
    from rig.config import ConfigError, load_config
    from rig.demo.settings import DEFAULT_CAUSE

    try:
        causes = load_config(config_path).virtual.causes
    except ConfigError as error:
        raise CommandError(str(error)) from None
    if not causes:
        return DEFAULT_CAUSE, params
    if len(causes) > 1 or params:
        raise CommandError(
            f"the rig file switches on {', '.join(causes)} in [virtual.causes]; the demo hides "
            "one effect: choose it with --cause NAME (and --param NAME=VALUE)"
        )
    (name, values), = causes.items()
    return name, dict(values)


def hidden_from_options(args: argparse.Namespace) -> HiddenCause:
    """The effect the demo's virtual rig hides: ``--cause`` with its ``--param`` values, else
    the one the rig file's ``[virtual.causes]`` switches on, else the default cause (a bad
    name or parameter is a :class:`~rig.demo.settings.DemoError` saying which)."""
    from rig.demo.settings import DEFAULT_CAUSE, DEFAULT_CAUSE_VALUES, hidden_cause

    params = _parse_params(args.param)
    name = args.cause
    if name is None:
        name, params = _cause_from_rig_file(args.config, params)
    if name == DEFAULT_CAUSE and not params:
        params = dict(DEFAULT_CAUSE_VALUES)
    return hidden_cause(name, params)


def run(args: argparse.Namespace) -> int:
    """Validate the options, run the demo, print where the report is."""
    from rig.config import ConfigError
    from rig.demo.record import prepare_folder
    from rig.demo.run import run_demo
    from rig.demo.settings import FULL, QUICK, DemoError

    started = time.monotonic()

    def timed_progress(text: str) -> None:
        progress(f"[{time.monotonic() - started:5.1f} s] {text}")

    try:
        hidden = hidden_from_options(args)
        prepare_folder(Path(args.out), overwrite=args.overwrite)  # refuse before any work
        result = run_demo(
            Path(args.out),
            settings=QUICK if args.quick else FULL,
            hidden=hidden,
            config_path=args.config,
            overwrite=True,
            progress=timed_progress,
        )
    except (DemoError, ConfigError) as error:
        raise CommandError(str(error)) from None
    print(result.summary())
    return 0
