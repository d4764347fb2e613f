"""Maps at scale: trajectories per second in one process and on N local Dask workers.

Each map is planned exactly as ``impact-rig map`` plans it, then computed twice in the
same run, alternately and --repeat times (the best of each counts, as other jobs may share
the machine): by one worker in this process (no pool: the reference) and by a LocalCluster
of N worker processes (one thread each).  Printed: trajectories per second of both, the
ratio (goal: at least 0.8 N for maps of 1000 or more trajectories), that both files hold
the same numbers bit for bit, the cluster's start-up time, and the scheduler's overhead
per task (empty tasks), with what it costs at the automatic batch size.

    nice -n 10 python benchmarks/bench_maps.py            # three maps of 1440-1800 runs
    nice -n 10 python benchmarks/bench_maps.py --quick    # smaller maps
    nice -n 10 python benchmarks/bench_maps.py --save     # also benchmarks/results/maps.json
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from analysis.maps import MapRunner, MapStore, read_map  # noqa: E402
from analysis.provenance import provenance  # noqa: E402
from harness.results import figure, result, save  # noqa: E402
from rig.cli import build_parser  # noqa: E402
from rig.commands.map import plan_from_args  # noqa: E402

MAPS = {
    # the Done-when map: 240 betas, up + down + 4 random initial states each
    "bifurcation": "bifurcation --f-drive-hz 10 --vary beta=0.02:0.6:240",
    "basins": "basins --f-drive-hz 10 --beta 0.08 --vary theta0=-0.6:0:40 "
    "--vary omega0=-8:8:40",
    "regimes": "regimes --vary beta=0.02:0.16:30 --vary f_drive_hz=8:12:30 --ics 2",
}
QUICK = {
    "bifurcation": "bifurcation --f-drive-hz 10 --vary beta=0.02:0.2:60",
    "basins": "basins --f-drive-hz 10 --beta 0.08 --vary theta0=-0.6:0:16 "
    "--vary omega0=-8:8:16",
    "regimes": "regimes --vary beta=0.02:0.16:12 --vary f_drive_hz=8:12:12 --ics 2",
}


def plan_of(command: str, out: Path):
    """The plan ``impact-rig map COMMAND --out OUT`` would compute."""
    return plan_from_args(build_parser().parse_args(["map", *command.split(), "--out", str(out)]))


def process_cpu_seconds() -> float:
    """User + system CPU time of the calling process."""
    import psutil

    times = psutil.Process().cpu_times()
    return times.user + times.system


def workers_cpu_seconds(runner: MapRunner) -> float:
    """CPU seconds used so far by the runner's worker processes (0 in this process)."""
    if runner.client is None:
        return 0.0
    return sum(runner.client.run(process_cpu_seconds).values())


def compute(runner: MapRunner, command: str, out: Path) -> tuple[float, float, int, int]:
    """Wall and CPU seconds (this process and the workers) to compute the whole map into a
    new file; trajectories and tasks."""
    plan = plan_of(command, out)
    store = MapStore.create(out, plan, provenance())
    cpu = process_cpu_seconds() + workers_cpu_seconds(runner)
    try:
        report = runner.run(plan, store)
    finally:
        store.close()
    cpu = process_cpu_seconds() + workers_cpu_seconds(runner) - cpu
    return report.seconds, cpu, plan.trajectories, len(plan.tasks)


def same_numbers(first: Path, second: Path) -> bool:
    """Every trajectory dataset equal bit for bit."""
    a, b = read_map(first)["trajectories"], read_map(second)["trajectories"]
    return all(a[name].tobytes() == b[name].tobytes() for name in a)


def scheduler_overhead(workers: int, tasks: int = 400) -> tuple[float, float]:
    """(throughput overhead per task, round-trip latency of one task) in seconds, for empty
    tasks on a LocalCluster like the maps' one."""
    from distributed import Client, LocalCluster

    with (
        LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                     dashboard_address=":0", silence_logs=logging.ERROR) as cluster,
        Client(cluster) as client,
    ):
        client.gather(client.map(abs, range(-workers * 4, 0)))  # connections warm
        start = time.perf_counter()
        client.gather(client.map(abs, range(tasks)))
        per_task = (time.perf_counter() - start) / tasks
        start = time.perf_counter()
        for k in range(50):
            client.submit(abs, -k - 1000).result()
        latency = (time.perf_counter() - start) / 50
    return per_task, latency


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller maps")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                        help="local Dask workers (default: one per core)")
    parser.add_argument("--repeat", type=int, default=3,
                        help="runs of each map on each side; the best counts (a shared machine)")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/maps.json")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    logging.getLogger("distributed").setLevel(logging.ERROR)
    maps = QUICK if args.quick else MAPS
    n = args.workers
    print(f"maps on 1 process vs {n} local Dask workers; load {os.getloadavg()[0]:.2f}")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        with MapRunner(workers=n) as cluster:
            startup = time.perf_counter() - started
            with MapRunner(workers=1) as one:
                for kind, command in maps.items():
                    times: dict[str, list[tuple[float, float]]] = {"1": [], "n": []}
                    for _ in range(args.repeat):  # alternating, so load changes hit both
                        for label, runner in (("1", one), ("n", cluster)):
                            out = Path(folder) / f"{kind}-{label}.h5"
                            out.unlink(missing_ok=True)
                            wall, cpu, count, tasks = compute(runner, command, out)
                            times[label].append((wall, cpu))
                    same = same_numbers(Path(folder) / f"{kind}-1.h5",
                                        Path(folder) / f"{kind}-n.h5")
                    rows.append((kind, count, tasks, min(times["1"]), min(times["n"]), same))
    print(f"(best of {args.repeat} alternating runs each; load now {os.getloadavg()[0]:.2f})")
    print(f"LocalCluster of {n} processes: ready (started, integrator loaded) in {startup:.2f} s")
    print(f"{'map':<12} {'runs':>6} {'tasks':>5} {'1 process':>20} {f'{n} workers':>20} "
          f"{'ratio':>6}  CPU s 1 / {n}   bit for bit")
    for kind, count, tasks, (t1, c1), (tn, cn), same in rows:
        print(f"{kind:<12} {count:>6} {tasks:>5} {count / t1:>8.0f}/s ({t1:6.2f} s) "
              f"{count / tn:>8.0f}/s ({tn:6.2f} s) {t1 / tn:>6.2f}  {c1:5.2f} / {cn:5.2f}"
              f"   {'yes' if same else 'NO'}")
    total1 = sum(r[3][0] for r in rows)
    totaln = sum(r[4][0] for r in rows)
    cpu1 = sum(r[3][1] for r in rows)
    cpun = sum(r[4][1] for r in rows)
    runs = sum(r[1] for r in rows)
    print(f"{'all':<12} {runs:>6} {'':>5} {runs / total1:>8.0f}/s ({total1:6.2f} s) "
          f"{runs / totaln:>8.0f}/s ({totaln:6.2f} s) {total1 / totaln:>6.2f}  "
          f"{cpu1:5.2f} / {cpun:5.2f}   (goal >= {0.8 * n:.1f})")
    print(f"CPU seconds on {n} workers (driver included) per CPU second in one process: "
          f"{cpun / cpu1:.2f}; with {n} free cores the ratio could reach about "
          f"{n * cpu1 / cpun:.2f} (less where a continuation sweep is the longest path)")
    per_task, latency = scheduler_overhead(n)
    per_run = total1 / runs
    print(f"scheduler overhead: {per_task * 1e3:.2f} ms per task at full throughput, "
          f"{latency * 1e3:.2f} ms round trip of one task; {per_run * 1e3:.2f} ms per "
          "trajectory in one process")
    for kind, count, tasks, *_ in rows:
        batch = count / tasks
        share = per_task / (batch * per_run + per_task)
        print(f"  {kind}: {tasks} tasks of {batch:.0f} trajectories on average (automatic "
              f"batch) -> overhead {100 * share:.2f} % of a task")
    if args.save:
        batch = runs / sum(r[2] for r in rows)
        share = per_task / (batch * per_run + per_task)
        identical = sum(row[5] for row in rows)
        counts = sorted(r[1] for r in rows)
        save(result("maps", [
            figure("maps identical bit for bit",
                   "all" if identical == len(rows) else f"{identical} of {len(rows)}", "all"),
            figure(f"speed-up, {n} workers against 1 process (best of {args.repeat} "
                   "alternating runs), all maps",
                   f"{total1 / totaln:.2f} (" + ", ".join(
                       f"{kind} {t1 / tn:.2f}" for kind, _, _, (t1, _), (tn, _), _ in rows) + ")",
                   f">= {0.8 * n:.1f} (0.8 N)"),
            figure(f"throughput, {n} workers / 1 process",
                   f"{runs / totaln:.0f} / {runs / total1:.0f} trajectories per s"),
            figure("workers' CPU seconds (driver included) per CPU second of the one process",
                   f"{cpun / cpu1:.2f}"),
            figure("scheduler cost per empty task at full throughput / round trip",
                   f"{per_task * 1e3:.1f} ms / {latency * 1e3:.1f} ms ({100 * share:.1f} % of a "
                   f"task at the automatic batch of {batch:.0f} trajectories)"),
            figure(f"LocalCluster of {n} processes ready (integrator loaded)", f"{startup:.1f} s"),
        ], about=f"`impact-rig map` on 1 process vs N local Dask workers: {len(rows)} maps of "
                 f"{counts[0]}-{counts[-1]} trajectories"
                 + ("" if args.quick else ", the Done-when bifurcation among them"),
           load_at_start=load))
    return 0 if all(row[5] for row in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
