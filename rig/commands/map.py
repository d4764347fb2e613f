"""``impact-rig map``: bifurcation diagrams, regime maps and basins of attraction at scale.

The map is cut into batched tasks that run in this process (``--workers 1``), on a local
Dask cluster (the default, one worker process per core) or on a Dask scheduler given by
address; the results are the same bit for bit.  Each finished task is written to the HDF5
file at once, so a run that was stopped continues when the same command is given again.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from analysis import quantities as q
from analysis.progress import MapProgress
from rig.cli import CommandError, add_command
from rig.logs import progress

KIND_DEFAULTS = {  # ics, transient periods, record periods
    "bifurcation": (4, 400, 100),
    "regimes": (4, 200, 64),
    "basins": (0, 200, 64),
}

DESCRIPTION = """\
Compute a map of the model's dynamics and write it to HDF5, with a PNG figure beside it.

  bifurcation  one parameter (--vary NAME=START:STOP:N), swept up and down by continuation
               (each step starts where the step before ended, as the experiment does), plus
               --ics random initial states per point to find coexisting attractors
  regimes      two parameters (--vary twice): at every point --ics random initial states;
               the dominant attractor's regime (period k, quasi-periodic, chaotic), its
               impacts per period, and how many attractors coexist
  basins       a grid of initial states (--vary theta0=... --vary omega0=..., rad and rad/s)
               for one model: which attractor each initial state settles on

Any model parameter can be set (--param NAME=VALUE, names as in 'impact-rig simulate') and
any can be varied.  Every trajectory runs --transient-periods drive periods, then records
--record-periods Poincare samples (drive phase 0).  Random initial states are drawn from
--seed and the point's index alone: theta0 uniform in [-0.6 rad, theta_b], theta_dot0
uniform in +-0.6 omega (omega = sqrt(g/L)).

Where it runs: --workers 1 runs here on one core, without any pool (the reference);
--workers N starts a local Dask cluster of N worker processes (default: one per core);
--scheduler tcp://HOST:8786 uses the workers of a running Dask scheduler (started with
'dask scheduler' and 'dask worker tcp://HOST:8786 --nthreads 1' on each machine, all with
the same impact-rig, numpy, numba versions installed).  Results are identical, bit for bit,
wherever they ran.  Tasks hold many trajectories each (--batch, chosen from the map's size
when not given).

The file is written task by task.  Run the same command again on an unfinished file and it
continues where it stopped; --overwrite starts again.  A finished file is left as it is.
"""

EPILOG = """\
examples:
  impact-rig map bifurcation --f-drive-hz 10 --vary beta=0.02:0.6:240 --out bif.h5
  impact-rig map regimes --vary beta=0.02:0.2:100 --vary f_drive_hz=6:14:100 --ics 2 \\
      --out regimes.h5
  impact-rig map basins --f-drive-hz 10 --beta 0.08 --vary theta0=-0.5:0:200 \\
      --vary omega0=-6:6:200 --out basins.h5
  impact-rig map bifurcation --f-drive-hz 10 --vary beta=0.02:0.15:200 --overlay sweep.h5 \\
      --out bif_and_sweep.h5
  impact-rig map bifurcation --f-drive-hz 10 --param beta=0.05 --vary zeta=0.002:0.03:100 \\
      --scheduler tcp://10.0.0.5:8786 --out zeta.h5
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``map`` sub-command."""
    parser = add_command(
        subparsers,
        "map",
        "bifurcation, regime or basin maps, on this machine or a Dask cluster -> HDF5 + PNG",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument("kind", choices=tuple(KIND_DEFAULTS), help="what to map")
    parser.add_argument(
        "--vary", action="append", default=[], metavar="NAME=START:STOP:N",
        help="a swept quantity, N values from START to STOP (once for bifurcation, twice "
        "for regimes and basins)",
    )
    parser.add_argument("--f-drive-hz", type=float, metavar="HZ", help="drive frequency [Hz]")
    parser.add_argument("--beta", type=float, help="drive amplitude as a fraction of L")
    parser.add_argument(
        "--param", action="append", default=[], metavar="NAME=VALUE",
        help="set a model parameter (repeatable; names as in 'impact-rig simulate --help')",
    )
    for option, metavar, text in (
        ("--ics", "M", "random initial states per point (bifurcation 4, regimes 4)"),
        ("--transient-periods", "P",
         "drive periods run and discarded first (bifurcation 400, others 200)"),
        ("--record-periods", "Q",
         "Poincare samples kept per trajectory, >= 50 (bifurcation 100, others 64)"),
    ):
        parser.add_argument(option, type=int, metavar=metavar, help=text)
    parser.add_argument(
        "--overlay", type=Path, metavar="SWEEP.h5",
        help="bifurcation: draw a recorded sweep (impact-rig sweep) over the diagram, the "
        "settled tach-pulse angles of each step, up and down in different marks",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the random initial states")
    parser.add_argument("--out", type=Path, required=True, help="output FILE.h5 (+ FILE.png)")
    parser.add_argument(
        "--overwrite", action="store_true", help="start again over an existing FILE.h5 and PNG"
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers", type=int, metavar="N",
        help="local worker processes (default: one per core); 1 runs in this process",
    )
    where.add_argument(
        "--scheduler", metavar="ADDRESS",
        help="a running Dask scheduler, e.g. tcp://127.0.0.1:8786 (its workers do the work)",
    )
    parser.add_argument(
        "--batch", type=int, default=0, metavar="N",
        help="trajectories per task (default: from the map's size, 64 to 1024)",
    )
    parser.add_argument(
        "--rtol", type=float, default=1e-8,
        help="integrator relative tolerance (1e-8); the absolute one is rtol / 100",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Check everything, plan the map, compute what the file lacks, summarize and draw."""
    import logging

    from analysis.maps import MapRunner, SchedulerError, finish_map
    from analysis.output_paths import HDF5_SUFFIXES, check_outputs, check_suffix

    plan = plan_from_args(args)  # every user error is found here, before anything runs
    check_suffix(args.out, HDF5_SUFFIXES, "a map (HDF5)")
    figure = args.out.with_suffix(".png")
    overlay = _overlay(args, plan)
    resume = args.out.exists() and not args.overwrite
    check_outputs([] if resume else [args.out, figure], overwrite=args.overwrite)
    if args.workers is not None and args.workers < 1:
        raise CommandError(f"--workers {args.workers}: need at least 1")
    if not args.verbose:
        logging.getLogger("distributed").setLevel(logging.ERROR)
    try:
        with MapRunner(args.workers, args.scheduler) as runner:  # reachable before any writing
            report = _compute(args, plan, runner, resume, figure)
            if report is None:
                return 0
            finish_map(args.out, figure, runner.map, overlay, runner.workers)  # on the workers
    except SchedulerError as error:
        raise CommandError(str(error)) from None
    progress(f"map {plan.kind}: attractors classified; figure {figure}")
    print(
        f"map {plan.kind}: {report.trajectories} trajectories computed in {report.seconds:.2f} s "
        f"({report.rate_per_s:.0f} per s) on {report.workers} worker(s), {report.where} "
        f"-> {args.out} + {figure.name}"
    )
    return 0


def _compute(
    args: argparse.Namespace, plan: Any, runner: Any, resume: bool, figure: Path
) -> Any:
    """Open (or continue) the file and run what it lacks; None when it was complete."""
    from analysis.maps import MapFileError, MapStore
    from analysis.provenance import provenance
    from rig.commands.rig_options import ProgressLine

    try:
        if resume:
            store = MapStore.resume(args.out, plan, provenance())
        else:
            args.out.unlink(missing_ok=True)
            store = MapStore.create(args.out, plan, provenance())
    except MapFileError as error:
        raise CommandError(str(error)) from None
    try:
        left = int((~store.done).sum())
        if resume and left == 0 and figure.exists():
            progress(f"{args.out}: the map is complete; nothing to do (--overwrite computes "
                 "it again)")
            return None
        if figure.exists() and not args.overwrite:  # not drawn by this map: never replaced
            raise CommandError(f"{figure}: already exists; pass --overwrite to replace it")
        progress(f"map {plan.kind}: {plan.trajectories} trajectories in {len(plan.tasks)} "
             f"tasks of up to {plan.batch} on {runner.workers} worker(s), {runner.where}"
             + (f"; {left} tasks left in {args.out}" if resume else ""))
        line = ProgressLine()
        return runner.run(plan, store, lambda p: line(_progress_text(p)))
    finally:
        store.close()


def plan_from_args(args: argparse.Namespace) -> Any:
    """The map the options describe; CommandError naming the option when they do not make one."""
    import numpy as np

    from analysis.maps import PlanError, basin_plan, bifurcation_plan, regime_plan
    from rig.commands.simulate import build_model

    axes = _axes_from_args(args)
    names = [axis.name for axis in axes]
    params = _fixed_values(args)
    _check_varied(args.kind, axes, params)
    settings = _settings_from_args(args)

    def packed(values: dict[str, float]) -> Any:
        model, _ = build_model(None, "forced", {**params, **values}, [])
        return model.pack()

    try:
        if args.kind == "basins":
            return basin_plan(packed({}), (axes[0], axes[1]), settings)
        grids = np.meshgrid(*[axis.values for axis in axes], indexing="ij")
        points = [dict(zip(names, map(float, values), strict=True))
                  for values in zip(*[grid.ravel() for grid in grids], strict=True)]
        vectors = np.array([packed(point) for point in points])
        _check_axes_matter(axes, vectors, grids[0].shape)
        if args.kind == "bifurcation":
            return bifurcation_plan(vectors, axes[0], settings)
        return regime_plan(vectors, (axes[0], axes[1]), settings)
    except PlanError as error:
        raise CommandError(str(error)) from None
    except CommandError as error:
        raise CommandError(f"{error} (while building the map's models)") from None


def _axes_from_args(args: argparse.Namespace) -> list[Any]:
    """The --vary axes, as many as the kind of map takes and each quantity once."""
    from analysis.maps import BASIN_AXES, Axis, AxisError

    wanted = {"bifurcation": 1, "regimes": 2, "basins": 2}[args.kind]
    if len(args.vary) != wanted:
        raise CommandError(
            f"map {args.kind} takes --vary {wanted} time(s), got {len(args.vary)}"
            + (f" ({' and '.join(BASIN_AXES)})" if args.kind == "basins" else "")
        )
    axes = []
    for text in args.vary:
        try:
            axes.append(Axis.parse(text))
        except AxisError as error:
            raise CommandError(f"--vary {error}") from None
    names = [axis.name for axis in axes]
    if len(set(names)) != len(names):
        raise CommandError(f"--vary: {names[0]} is varied twice")
    return axes


def _fixed_values(args: argparse.Namespace) -> dict[str, float]:
    """The model values held over the map: --param, --f-drive-hz and --beta (each once)."""
    from rig.commands.simulate import parse_assignments

    params = parse_assignments(args.param)
    for option, name in (("--f-drive-hz", q.f_drive_hz), ("--beta", q.beta)):
        value = getattr(args, name)
        if value is not None:
            if name in params:
                raise CommandError(f"{option} and --param {name} both given: give one")
            params[name] = value
    return params


def _check_varied(kind: str, axes: list[Any], params: dict[str, float]) -> None:
    """A basin map varies the initial state (axes put in BASIN_AXES order); the others vary
    model parameters that are known and not also held fixed."""
    from analysis.maps import BASIN_AXES
    from rig.commands.simulate import parameter_names

    names = [axis.name for axis in axes]
    if kind == "basins":
        if sorted(names) != sorted(BASIN_AXES):
            raise CommandError(
                f"--vary {', '.join(names)}: a basin map varies the initial state, "
                f"{' and '.join(BASIN_AXES)} (rad, rad/s)"
            )
        axes.sort(key=lambda axis: BASIN_AXES.index(axis.name))
        return
    for name in names:
        if name in BASIN_AXES:
            raise CommandError(
                f"--vary {name}: initial states are varied in 'map basins'; here they are "
                "random (--ics)"
            )
        if name in params:
            raise CommandError(f"--vary {name} and a fixed value of {name}: give one")
        if name not in parameter_names():
            raise CommandError(
                f"--vary {name}: unknown parameter; valid names: {', '.join(parameter_names())}"
            )


def _settings_from_args(args: argparse.Namespace) -> Any:
    """The integration and sampling settings, the kind's defaults where an option is not given."""
    from analysis.maps import MapSettings, PlanError

    ics, transient, record = KIND_DEFAULTS[args.kind]
    if args.kind == "basins" and args.ics:
        raise CommandError("--ics: a basin map's initial states are its grid (--vary)")
    if not (math.isfinite(args.rtol) and 0 < args.rtol < 1):
        raise CommandError(f"--rtol {args.rtol}: must lie in (0, 1)")
    try:
        return MapSettings(
            transient_periods=_given(args.transient_periods, transient),
            record_periods=_given(args.record_periods, record),
            ics=_given(args.ics, ics),
            seed=args.seed,
            batch=args.batch,
            rtol=args.rtol,
            atol=args.rtol * 1e-2,
        )
    except PlanError as error:
        raise CommandError(str(error)) from None


def _check_axes_matter(axes: list[Any], vectors: Any, shape: tuple[int, ...]) -> None:
    """Refuse an axis whose values do not change the model (overridden by another setting)."""
    import numpy as np

    grid = vectors.reshape(*shape, -1)
    for k, axis in enumerate(axes):
        if axis.count > 1:
            ends = np.take(grid, [0, -1], axis=k)
            if np.array_equal(ends[(slice(None),) * k + (0,)], ends[(slice(None),) * k + (1,)]):
                raise CommandError(
                    f"--vary {axis.name}: its values do not change the model (another "
                    "setting overrides it, e.g. A_m over beta)"
                )


def _overlay(args: argparse.Namespace, plan: Any) -> Any:
    """The recorded sweep to draw over a bifurcation map (None without --overlay)."""
    if args.overlay is None:
        return None
    from analysis.maps.overlay import recorded_sweep
    from recording.errors import RecordFormatError

    if plan.kind != "bifurcation":
        raise CommandError("--overlay: a recorded sweep is drawn over a bifurcation map only")
    if not args.overlay.is_file():
        raise CommandError(f"--overlay {args.overlay}: no such file")
    try:
        return recorded_sweep(args.overlay, plan.axes[0].name)
    except (RecordFormatError, OSError, KeyError) as error:
        raise CommandError(f"--overlay {error}") from None


def _given(value: int | None, default: int) -> int:
    return default if value is None else value


def _progress_text(state: MapProgress) -> str:
    rate = state.rate_per_s
    speed = f"{rate:.0f} trajectories/s" if math.isfinite(rate) else "starting"
    eta = f"ETA {state.eta_s:.0f} s" if math.isfinite(state.eta_s) else "ETA -"
    return (
        f"map: {state.tasks.done}/{state.tasks.total} tasks, "
        f"{state.trajectories.done}/{state.trajectories.total} trajectories, "
        f"{speed}, {eta}"
    )


