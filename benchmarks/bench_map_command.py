"""The map command's own time: ``impact-rig map`` as a whole against its trajectories alone.

A 60 x 60 regime map with 2 random initial states per point (7 200 trajectories) is
computed, in the same run, alternately and --repeat times (the best of each counts, as
other jobs may share the machine), in one process (``--workers 1``) and on a local Dask
cluster of 2 worker processes:

- the whole command, as a user runs it: a new process, from its start (imports, the
  plan, the integrator loaded, the workers started) to its end (the attractors
  classified, the summary stored, the figure drawn), wall time; and the time the command
  itself says its trajectories took (tasks run and written, in the same process and so
  under the same load: the steadier figure on a shared machine);
- the trajectories alone: every task of the same plan run here (``run_task``, nothing
  written), or on a cluster already started and warmed up, results gathered, wall time.

Printed: the times and the ratios of the whole command to both (goal: at most 1.1), and
whether the two commands' files hold the same map bit for bit.  The machine is shared:
read the ratios, not the seconds.

    nice -n 10 python benchmarks/bench_map_command.py           # 60 x 60 x 2
    nice -n 10 python benchmarks/bench_map_command.py --quick   # 20 x 20 x 2
    python benchmarks/bench_map_command.py --save    (also benchmarks/results/map-command.json)
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from analysis.maps import MapRunner, read_map  # noqa: E402
from analysis.maps.tasks import run_task, task_input  # noqa: E402
from harness.results import figure, result, save  # noqa: E402
from rig.cli import build_parser  # noqa: E402
from rig.commands.map import plan_from_args  # noqa: E402

MAP = "regimes --vary beta=0.02:0.16:{n} --vary f_drive_hz=8:12:{n} --ics 2"
SIZE, QUICK_SIZE = 60, 20
WORKERS = (1, 2)
GOAL = 1.1


def whole_command(command: str, workers: int, out: Path) -> tuple[float, float]:
    """Wall seconds of ``impact-rig map COMMAND --workers N`` in a new process, and of its
    trajectories as it reports them."""
    out.unlink(missing_ok=True)
    out.with_suffix(".png").unlink(missing_ok=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    started = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", "map", *command.split(), "--workers", str(workers),
         "--quiet", "--out", str(out)],
        check=True, env=env, cwd=ROOT, stdout=subprocess.PIPE, text=True,
    )
    seconds = time.perf_counter() - started
    return seconds, float(re.search(r"computed in ([0-9.]+) s", done.stdout).group(1))


def trajectories_alone(runner: MapRunner, inputs: list) -> float:
    """Wall seconds to run every task on ``runner`` (started and warm), nothing written."""
    started = time.perf_counter()
    runner.map(run_task, inputs)
    return time.perf_counter() - started


def same_map(first: Path, second: Path) -> bool:
    """The two files' trajectories and summaries equal bit for bit."""
    a, b = read_map(first), read_map(second)
    return all(
        a[group].keys() == b[group].keys()
        and all(a[group][name].tobytes() == b[group][name].tobytes() for name in a[group])
        for group in ("trajectories", "summary")
    ) and a["summary_info"] == b["summary_info"]


def main() -> int:
    """Time the whole command and its trajectories on 1 process and 2 workers; print the
    ratios (and save them with --save)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 20 x 20 x 2 map")
    parser.add_argument("--repeat", type=int, default=2,
                        help="runs of each measurement; the best counts (a shared machine)")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/map-command.json")
    args = parser.parse_args()
    logging.getLogger("distributed").setLevel(logging.ERROR)
    load = os.getloadavg()[0]
    size = QUICK_SIZE if args.quick else SIZE
    command = MAP.format(n=size)
    plan = plan_from_args(build_parser().parse_args(["map", *command.split(), "--out", "x.h5"]))
    inputs = [task_input(plan, task) for task in plan.tasks]
    print(f"impact-rig map {command}: {plan.trajectories} trajectories in {len(inputs)} tasks; "
          f"load {load:.2f}")
    whole: dict[int, list[tuple[float, float]]] = {n: [] for n in WORKERS}
    alone: dict[int, list[float]] = {n: [] for n in WORKERS}
    with tempfile.TemporaryDirectory() as folder:
        for run in range(args.repeat):  # alternating, so load changes hit both
            for n in WORKERS:
                whole[n].append(whole_command(command, n, Path(folder) / f"map-{n}.h5"))
                with MapRunner(workers=n) as runner:  # started and warm before the timing
                    alone[n].append(trajectories_alone(runner, inputs))
                (w, own), t = whole[n][-1], alone[n][-1]
                print(f"  run {run + 1}, {n} worker(s): whole command {w:.2f} s (its "
                      f"trajectories {own:.2f} s), trajectories alone {t:.2f} s", flush=True)
        same = same_map(Path(folder) / "map-1.h5", Path(folder) / "map-2.h5")
    print(f"(best of {args.repeat} alternating runs each; load now {os.getloadavg()[0]:.2f})")
    print(f"{'where':<12} {'whole command':>14} {'its trajectories':>17} {'ratio':>6} "
          f"{'trajectories alone':>19} {'ratio':>6}   (goal <= {GOAL})")
    ratios, own_ratios = {}, {}
    for n in WORKERS:
        (w, own), t = min(whole[n]), min(alone[n])
        own_ratios[n] = min(whole_s / own_s for whole_s, own_s in whole[n])
        ratios[n] = w / t
        where = "1 process" if n == 1 else f"{n} workers"
        print(f"{where:<12} {w:>12.2f} s {own:>15.2f} s {own_ratios[n]:>6.2f} {t:>17.2f} s "
              f"{ratios[n]:>6.2f}")
    print(f"the two commands' maps identical bit for bit: {'yes' if same else 'NO'}")
    if args.save:
        save(result("map-command", [
            figure(f"whole command / the trajectories it reports, {size} x {size} x 2 regime "
                   "map, 1 process / 2 local Dask workers",
                   f"{own_ratios[1]:.2f} / {own_ratios[2]:.2f}", f"<= {GOAL}"),
            figure("whole command / its tasks run alone (nothing written, workers warm), "
                   "1 process / 2 workers", f"{ratios[1]:.2f} / {ratios[2]:.2f}",
                   f"<= {GOAL}"),
            figure("the two commands' maps identical bit for bit", "yes" if same else "NO",
                   "yes"),
        ], about=f"`impact-rig map` as a whole (a new process, best of {args.repeat}) against "
           "its tasks run alone, alternately in the same run", load_at_start=load))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
