"""Dynamics tools at production size: bifurcation diagram and basin map of the 10 Hz paper rig.

* Bifurcation: 400 beta values in [0.01, 0.13] (paper case h's rig), 500 drive
  periods per value (last 100 recorded), continuation up and down (the two sweeps
  in lockstep, two-member ensemble calls), and the same from a fixed initial state (all cores).
* Basins: a 200 x 200 grid of initial states for paper case d, 200 periods of
  transient + 64 recorded, every point identified against the attractor catalogue.

Baseline, measured in the same run: plain in-process ``simulate_packed`` calls on a
sample of the job's own runs (20 betas, 40 grid points), scaled to the number of
runs, i.e. the serial cost of the simulations alone.  The ratio (time / baseline)
shows what parallel workers win and what the bookkeeping (Poincare extraction,
attractor matching) costs.

    python benchmarks/bench_dynamics.py            # full size (several minutes on 2 cores)
    python benchmarks/bench_dynamics.py --quick    # 40 betas, 30 x 30 grid
    python benchmarks/bench_dynamics.py --save     # also benchmarks/results/dynamics.json
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from analysis.dynamics import (  # noqa: E402
    basins_of_attraction,
    model_at_beta,
    plot_basins,
    plot_bifurcation,
    simulate_bifurcation,
)
from analysis.dynamics.sweeps import default_workers  # noqa: E402
from analysis.model import Model, paper_case  # noqa: E402
from analysis.packed import P  # noqa: E402
from analysis.simulate import SimulationSettings, simulate_ensemble, simulate_packed  # noqa: E402
from harness.results import figure, result, save  # noqa: E402


def serial_seconds_per_run(packed: np.ndarray, initial: np.ndarray, periods: int) -> float:
    """Mean time of plain in-process simulate_packed calls over a sample of the job's runs."""
    period = 2.0 * math.pi / packed[0, P.OMEGA_DRIVE]
    # load (or compile) the numba code of both paths before timing anything
    simulate_packed(
        packed[0], 0.0, 0.0,
        settings=SimulationSettings(duration_s=period, fs_hz=1.0 / period),
    )
    simulate_ensemble(packed[:2], initial[:2], duration_s=period)
    start = time.perf_counter()
    for p, (theta0, theta_dot0) in zip(packed, initial, strict=True):
        simulate_packed(
            p, theta0, theta_dot0,
            settings=SimulationSettings(
                duration_s=periods * period, fs_hz=1.0 / period, rtol=1e-8, atol=1e-10,
            ),
        )
    return (time.perf_counter() - start) / packed.shape[0]


def bench_bifurcation(n_betas: int, periods: int, out: Path | None) -> dict[str, float]:
    """Print and return the seconds of each mode (continuation, fixed)."""
    rig, drive = paper_case("h").dimensional()
    base = Model(rig, drive)
    betas = np.linspace(0.01, 0.13, n_betas)
    sample = betas[:: max(1, n_betas // 20)]
    packed = np.array([model_at_beta(base, b).pack() for b in sample])
    per_run = serial_seconds_per_run(packed, np.zeros((sample.size, 2)), periods)
    print(f"bifurcation: {n_betas} betas x {periods} periods, workers: {default_workers()}")
    print(
        f"  baseline: a {periods}-period run takes {per_run * 1e3:.1f} ms serially "
        f"(mean over {sample.size} betas)"
    )
    seconds = {}
    for mode, runs in (("continuation", 2 * n_betas), ("fixed", n_betas)):
        start = time.perf_counter()
        diagrams = simulate_bifurcation(base, betas, periods=periods, record_periods=100, mode=mode)
        elapsed = seconds[mode] = time.perf_counter() - start
        baseline = runs * per_run
        print(
            f"  {mode:>12}: {elapsed:7.2f} s for {runs} runs; serial baseline {baseline:7.2f} s; "
            f"ratio {elapsed / baseline:.2f}"
        )
        if out is not None and mode == "continuation":
            plot_bifurcation(*diagrams, title="paper case h rig", path=out / "bifurcation.png")
    return seconds


def bench_basins(n_grid: int, out: Path | None) -> float:
    """Print and return the seconds of the basin map."""
    rig, drive = paper_case("d").dimensional()
    model = Model(rig, drive)
    transient, record = 200, 64
    theta0 = np.linspace(-0.6, 0.05, n_grid)
    theta_dot0 = np.linspace(-6.0, 6.0, n_grid)
    grid = np.column_stack([g.ravel() for g in np.meshgrid(theta0, theta_dot0)])
    sample = grid[np.random.default_rng(0).choice(grid.shape[0], 40, replace=False)]
    per_run = serial_seconds_per_run(np.tile(model.pack(), (40, 1)), sample, transient + record)
    runs = n_grid * n_grid
    print(f"basins: {n_grid} x {n_grid} grid, {transient} + {record} periods per point")
    print(f"  baseline: a run takes {per_run * 1e3:.1f} ms serially (mean over 40 grid points)")
    start = time.perf_counter()
    basins = basins_of_attraction(
        model, theta0, theta_dot0, transient_periods=transient, record_periods=record
    )
    elapsed = time.perf_counter() - start
    baseline = runs * per_run
    names = ", ".join(f"{a.name} {100 * a.basin_fraction:.1f} %" for a in basins.attractors)
    print(
        f"  basins: {elapsed:7.2f} s for {runs} runs; serial baseline {baseline:7.2f} s; "
        f"ratio {elapsed / baseline:.2f}; attractors: {names}"
    )
    if out is not None:
        plot_basins(basins, title="paper case d", path=out / "basins.png")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (40 betas, 30 x 30)")
    parser.add_argument("--figures", type=Path, help="write bifurcation.png and basins.png here")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/dynamics.json")
    args = parser.parse_args()
    if args.figures is not None:
        args.figures.mkdir(parents=True, exist_ok=True)
    load = os.getloadavg()[0]
    n_betas, n_grid = (40, 30) if args.quick else (400, 200)
    bifurcation = bench_bifurcation(n_betas, 500, args.figures)
    basins = bench_basins(n_grid, args.figures)
    if args.save:
        save(result("dynamics", [
            figure(f"bifurcation diagram, {n_betas} betas x 500 periods (fixed start / "
                   "continuation up + down)",
                   f"{bifurcation['fixed']:.3g} s / {bifurcation['continuation']:.3g} s"),
            figure(f"basins, {n_grid} x {n_grid} grid", f"{basins:.3g} s"),
        ], load_at_start=load))


if __name__ == "__main__":
    main()
