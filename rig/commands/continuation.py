"""``impact-rig continue``: follow periodic orbits through a parameter, stable and unstable."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from analysis import quantities as q
from rig.cli import CommandError, add_command

SETTLE_PERIODS = 2000

DESCRIPTION = """\
Follow the period-K orbit of the forced pendulum through one model parameter, stable and
unstable, by pseudo-arclength continuation of the fixed points of the K-th iterate of the
drive-period (stroboscopic) map; each orbit comes with its Floquet multipliers (from the
map's exact sensitivities through every contact; from central differences with Coulomb
friction, which the last line then says).
Period-doublings (a multiplier through -1), folds (the parameter turns back), branch points
(a multiplier through +1 without a turn) and grazings (a swing's apex reaching the barrier)
are located to about 1e-9 of the parameter range; at each period-doubling the period-2K
orbit is followed too, up to --max-period.

The start is the orbit nearest --from-state at START (default: the state a run from rest
settles to in 2000 drive periods). Parameters start from the paper's rig (or --case) and
--param, as in 'impact-rig simulate'; the varied one starts at START.

Writes FILE.h5 (branches: parameter, state at drive phase 0, multipliers, stability,
largest angle, barrier distance, contacts, the angles at drive phase 0; the events;
provenance) and FILE.png (largest angle against the parameter: stable solid, unstable
dashed, every event numbered and listed with its value and multipliers).

What a brute-force diagram shows is only the attractors its runs fall into: with
--brute-force N (N parameter values, each run settled from the previous one, upwards and
downwards, as the experiment does) and --overlay SWEEP.h5 (a recording of 'impact-rig
sweep' over beta or the drive frequency) a second panel draws their points at drive
phase 0 under the branches' k angles at drive phase 0, so one sees which orbit a sweep
sits on, and where it leaves it.
"""

EPILOG = """\
examples:
  impact-rig continue --case g --vary beta=0.01:0.04 --period 2 --out case_g_p2.h5
  impact-rig continue --f-drive-hz 10 --vary beta=0.005:0.04 --param theta_b_rad=0.02 \\
      --from-state 0,0 --out gap.h5
  impact-rig continue --f-drive-hz 2.6 --vary f_drive_hz=2.6:2.0 --param beta=0.0016 \\
      --param zeta=0.002 --no-barrier --out resonance.h5
  impact-rig continue --case g --vary beta=0.01:0.13 --period 2 --brute-force 120 \\
      --overlay sweep10hz.h5 --out ten_hz.h5
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``continue`` sub-command."""
    parser = add_command(
        subparsers,
        "continue",
        "follow periodic orbits through a parameter: multipliers, period-doublings, "
        "folds, grazings",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument("--f-drive-hz", type=float, metavar="F", help="drive frequency [Hz]")
    parser.add_argument("--case", help="start from the paper's forced case a..i")
    parser.add_argument("--vary", required=True, metavar="NAME=START:STOP",
                        help="the parameter and its range, e.g. beta=0.01:0.04 (names as for "
                        "--param; also f_drive_hz)")
    parser.add_argument("--period", type=int, default=1, metavar="K",
                        help="drive periods of the orbit followed first (1)")
    parser.add_argument("--max-period", type=int, metavar="N",
                        help="follow period-doubled branches up to this period (4 K)")
    parser.add_argument("--from-state", metavar="THETA,OMEGA",
                        help="guess of the orbit's state at drive phase 0 [rad, rad/s]; "
                        "with a negative angle write --from-state=-0.12,-0.7")
    parser.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="set a parameter (repeatable; see 'impact-rig simulate --help')")
    parser.add_argument("--cause", action="append", default=[], metavar="NAME",
                        help="switch on a named cause of docs/MODEL.md section 6 (repeatable)")
    parser.add_argument("--no-barrier", action="store_true", help="remove the barrier")
    parser.add_argument("--overlay", action="extend", nargs="+", default=[], type=Path,
                        metavar="FILE.h5", help="draw the Poincare points of these files under "
                        "the branches: recordings of 'impact-rig sweep' (repeatable)")
    parser.add_argument("--brute-force", type=int, default=0, metavar="N",
                        help="also simulate the brute-force diagram at N values over the "
                        "range (up and down, each from the previous state) and draw it")
    parser.add_argument("--brute-force-periods", type=int, default=500, metavar="P",
                        help="drive periods per value of --brute-force, the last fifth "
                        "recorded (500)")
    parser.add_argument("--out", type=Path, required=True,
                        help="output FILE.h5; the figure goes to FILE.png beside it")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.set_defaults(func=run)


def _parse_vary(text: str) -> tuple[str, float, float]:
    name, sep, span = text.partition("=")
    start, colon, stop = span.partition(":")
    try:
        values = float(start), float(stop)
    except ValueError:
        values = ()
    if not sep or not colon or not name.strip() or len(values) != 2 or not all(
        math.isfinite(v) for v in values
    ):
        raise CommandError(f"--vary {text!r}: expected NAME=START:STOP, e.g. beta=0.01:0.04")
    if values[0] == values[1]:
        raise CommandError(f"--vary {text!r}: START and STOP are equal")
    return name.strip(), values[0], values[1]


def _parse_state(text: str) -> tuple[float, float]:
    parts = text.split(",")
    try:
        theta, omega = (float(p) for p in parts)
    except ValueError:
        raise CommandError(
            f"--from-state {text!r}: expected THETA,OMEGA in rad and rad/s, e.g. -0.12,-0.7"
        ) from None
    if not (math.isfinite(theta) and math.isfinite(omega)):
        raise CommandError(f"--from-state {text!r}: values must be finite")
    return theta, omega


def run(args: argparse.Namespace) -> int:
    """Build the model, find the first orbit, continue, write the file and the figure."""
    import numpy as np

    from analysis.dynamics.continuation import ContinuationError, continue_orbits
    from analysis.dynamics.continuation_output import plot_continuation, write_continuation
    from analysis.dynamics.model_parameters import DRIVE_PARAMETERS, model_with
    from analysis.dynamics.period_map import PeriodMap
    from analysis.output_paths import check_outputs
    from analysis.packed import ParameterError
    from analysis.provenance import provenance
    from rig.commands.rig_options import ProgressLine
    from rig.commands.simulate import build_model, parse_assignments

    _check_arguments(args)
    figure_path = args.out.with_suffix(".png")
    check_outputs([args.out, figure_path], overwrite=args.overwrite)
    name, start, stop = _parse_vary(args.vary)
    params = parse_assignments(args.param)
    if args.f_drive_hz is not None:
        params[q.f_drive_hz] = args.f_drive_hz
    if name in DRIVE_PARAMETERS:
        params[name] = start
    if q.f_drive_hz not in params and not args.case:
        raise CommandError("the drive frequency is needed: --f-drive-hz F (or --case)")
    if not any(k in params for k in (q.beta, q.A_m)) and not args.case:
        raise CommandError("the drive amplitude is needed: --param beta=... or A_m=..., "
                           "or vary it with --vary beta=START:STOP")
    model, _ = build_model(args.case, "forced", params, args.cause)
    if args.no_barrier:
        from dataclasses import replace

        model = replace(model, barrier=False)
    try:
        model = model_with(model, name, start)
        period_map = PeriodMap(model, name, args.period)
    except (ParameterError, ValueError) as error:
        raise CommandError(f"--vary {args.vary}: {error}") from None
    progress = ProgressLine()
    guess = _initial_state(args, model, f"{name} = {start:g}", progress)
    max_period = args.max_period if args.max_period is not None else 4 * args.period
    try:
        result = continue_orbits(period_map, start, stop, guess, max_periods=max_period,
                                 progress=progress)
    except ContinuationError as error:
        raise CommandError(f"no period-{args.period} orbit to start from: {error}") from None
    overlays, described = _overlays(args, model, name, start, stop, progress)
    write_continuation(args.out, result, model, provenance(), described)
    title = f"{name} from {start:g} to {stop:g}, drive {model.drive.frequency_hz:g} Hz"
    barrier = model.rig.theta_b_rad if model.barrier else None
    plot_continuation(result, overlays=overlays, barrier_rad=barrier, title=title,
                      path=figure_path)
    for i, branch in enumerate(result.branches):
        print(f"branch {i}: period {branch.periods}, {len(branch.points)} points, "
              f"{int(branch.stable.sum())} stable; {branch.origin}; {branch.stop_reason}")
    for event in result.events:
        print(f"  {event.kind} on branch {event.branch} (period {event.periods}) at {name} = "
              f"{event.value:.9g} ({_bracket_text(event.bracket)}), "
              f"multipliers {np.round(event.point.multipliers, 4).tolist()}")
    print(f"continue: {result.points} orbits in {result.seconds:.2f} s "
          f"({1e3 * result.seconds_per_point:.1f} ms per point; Jacobians: {result.jacobians}) "
          f"-> {args.out}, {figure_path.name}", file=sys.stdout)
    return 0


def _check_arguments(args: argparse.Namespace) -> None:
    """Refuse an output name, period, brute-force setting or overlay that cannot work."""
    from analysis.output_paths import HDF5_SUFFIXES, check_suffix

    check_suffix(args.out, HDF5_SUFFIXES, "a continuation (HDF5)")
    if args.period < 1:
        raise CommandError(f"--period {args.period}: must be at least 1")
    if args.brute_force < 0 or args.brute_force == 1 or args.brute_force_periods < 5:
        raise CommandError("--brute-force N needs N >= 2 values and --brute-force-periods >= 5")
    for overlay in args.overlay:
        if not overlay.is_file():
            raise CommandError(f"--overlay {overlay}: no such file")


def _initial_state(args: argparse.Namespace, model, where: str, progress):
    """Where the search for the first orbit starts: --from-state, or (theta, theta') at
    drive phase 0 after SETTLE_PERIODS drive periods from rest."""
    import numpy as np

    from analysis.simulate import SimulationSettings, simulate

    if args.from_state:
        return np.array(_parse_state(args.from_state))
    progress(f"settling: {SETTLE_PERIODS} drive periods from rest at {where}")
    period_s = 1.0 / model.drive.frequency_hz
    settled = simulate(
        model, 0.0, 0.0,
        settings=SimulationSettings(
            duration_s=period_s, fs_hz=1.0 / period_s, skip_s=SETTLE_PERIODS * period_s,
        ),
    )
    if not settled.ok or settled.poincare.theta.size == 0:
        raise CommandError(f"the run from rest stopped ({settled.status}); give --from-state")
    return np.array([settled.poincare.theta[-1], settled.poincare.theta_dot[-1]])


def _overlays(args: argparse.Namespace, model, name: str, start: float, stop: float, progress):
    """The diagrams to draw under the branches, and what each is (for the file)."""
    import numpy as np

    from analysis.dynamics.bifurcation import simulate_bifurcation
    from analysis.dynamics.diagram_files import DiagramFileError, read_diagrams

    diagrams, described = [], []
    for path in args.overlay:
        try:
            found = read_diagrams(path, name)
        except DiagramFileError as error:
            raise CommandError(f"--overlay: {error}") from None
        diagrams += found
        described.append({"file": str(path), "directions": [d.direction for d in found]})
    if args.brute_force:
        values = np.linspace(min(start, stop), max(start, stop), args.brute_force)
        periods = args.brute_force_periods
        progress(f"brute force: {values.size} values of {name} x {periods} periods, up and down")
        try:
            found = simulate_bifurcation(model, values, periods=periods,
                                         record_periods=max(periods // 5, 1), parameter=name)
        except ValueError as error:  # e.g. runs at several drive frequencies
            raise CommandError(f"--brute-force over {name}: {error}") from None
        diagrams += found
        described.append({"brute_force": {"values": values.size, "periods": periods,
                                          "record_periods": max(periods // 5, 1)},
                          "directions": [d.direction for d in found]})
    return diagrams, described


def _bracket_text(bracket: tuple[float, float]) -> str:
    """The width of a located event's bracket, or why there is none."""
    width = bracket[1] - bracket[0]
    return f"bracket {width:.1g}" if math.isfinite(width) else "the branch stops short of it"
