"""The README's continuation gallery: the paper's case (g) and the 10 Hz sweep, regenerated.

    python benchmarks/continuation_gallery.py [--figures docs/figures] [--work DIR]

1. Case (g), beta 0.01 to 0.04: the period-1 and period-2 orbits continued (what
   ``impact-rig continue --case g --vary beta=0.01:0.04 --period 1`` and ``--period 2``
   compute), one figure with both and a brute-force diagram (61 values, up and down)
   under them -> continuation_case_g.png.
2. The basin map of case (g) at beta = 0.022, 41 x 41 initial states -> basins_case_g.png.
3. A search for other periodic orbits of case (g) at beta = 0.022: Newton's method on P^k,
   k = 1 to 8, from every close return (within 0.01) of 200 transients of 60 periods
   from random states; prints each distinct orbit found, its multipliers and stability.
4. The 10 Hz case: ``impact-rig continue --case g --vary beta=0.01:0.13 --period 2
   --brute-force 120 --overlay SWEEP.h5`` over a sweep recorded on the virtual rig
   (``impact-rig sweep --sim``, beta 0.02 to 0.125 and back, about 2 minutes; kept in
   --work and reused) -> the command's own figure, copied to continuation_10hz.png.

Prints the located events and the seconds per continuation point.  Run it with ``nice``:
it takes about 4 minutes on 2 cores.

    python benchmarks/continuation_gallery.py --compare-jacobians [--repeats 2] [--save]

draws no figure: it runs the three continuations above (case (g) period 1 and 2 over beta
0.01 to 0.04, and the 10 Hz period-2 orbit over beta 0.01 to 0.13 from the state a run
from rest settles to, as the command starts it) with the Jacobians from the sensitivities
and from central differences, alternately in one process (after one short warm-up of
each), prints every event of both, the largest difference between the events both found
and between their brackets' ends, and the CPU time per point of each (the best of
``--repeats``: CPU time, not wall time, so that a shared machine's other work counts
less) and their ratio; ``--save`` writes the figures to
``benchmarks/results/continuation.json``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.dynamics.basins import basins_of_attraction, plot_basins
from analysis.dynamics.bifurcation import simulate_bifurcation
from analysis.dynamics.continuation import ContinuationResult, continue_orbits
from analysis.dynamics.continuation_output import plot_continuation
from analysis.dynamics.model_parameters import model_with
from analysis.dynamics.period_map import PeriodMap
from analysis.dynamics.periodic_orbits import ShootingError, find_periodic_orbit
from analysis.dynamics.sweeps import PoincareSettings, run_poincare
from analysis.model import Model, paper_case
from analysis.simulate import SimulationSettings, simulate
from harness.results import figure, result, save
from rig.cli import add_common_options
from rig.cli import main as rig_main
from rig.commands import continuation
from rig.config import load_config

DPI = 90  # README figures stay well under 200 kB
SWEEP_BETAS = (0.02, 0.035, 0.05, 0.065, 0.08, 0.095, 0.11, 0.125)  # the demo's sweep


def case_g(beta: float = 0.022) -> Model:
    """The paper's case (g) (10 Hz) at ``beta``."""
    rig, drive = paper_case("g").dimensional()
    return model_with(Model(rig, drive), "beta", beta)


def report(result: ContinuationResult, what: str) -> None:
    """One line per branch and event, and the time per point."""
    print(f"{what}: {result.points} orbits in {result.seconds:.2f} s "
          f"({1e3 * result.seconds_per_point:.1f} ms per point)")
    for i, branch in enumerate(result.branches):
        moduli = np.abs(branch.multipliers).max(axis=1)
        print(f"  branch {i}: period {branch.periods}, {branch.values.min():.4g}..."
              f"{branch.values.max():.4g}, {int(branch.stable.sum())}/{len(branch.points)} "
              f"stable, largest |multiplier| {moduli.min():.3g}..{moduli.max():.3g}; "
              f"{branch.stop_reason}")
    for event in result.events:
        print(f"  {event.kind} on branch {event.branch} (period {event.periods}) at "
              f"{result.parameter} = {event.value:.9g}")


def gallery_case_g(figures: Path) -> None:
    """Period-1 and period-2 branches over beta 0.01..0.04 with a brute-force diagram."""
    model = case_g(0.01)
    branches, seconds = [], 0.0
    for periods, guess in ((1, (-0.012, -0.73)), (2, (-0.028, -1.44))):
        result = continue_orbits(PeriodMap(model, "beta", periods), 0.01, 0.04,
                                 np.array(guess), max_periods=4)
        report(result, f"case (g), period {periods}")
        branches += result.branches
        seconds += result.seconds
    both = ContinuationResult("beta", (0.01, 0.04), branches, seconds, result.map_rtol,
                              result.jacobians)
    brute = simulate_bifurcation(model, np.linspace(0.01, 0.04, 61), periods=1000,
                                 record_periods=100)
    plot_continuation(both, overlays=brute, barrier_rad=model.rig.theta_b_rad, dpi=DPI,
                      title="case (g), 10 Hz: period-1 and period-2 orbits, beta 0.01 to 0.04",
                      path=figures / "continuation_case_g.png")


def basins_case_g(figures: Path) -> None:
    """The basin map of case (g) at beta = 0.022."""
    started = time.perf_counter()
    basin_map = basins_of_attraction(case_g(), np.linspace(-0.4, 0.0, 41),
                                     np.linspace(-8.0, 8.0, 41), transient_periods=400,
                                     record_periods=64)
    print(f"basins of case (g) at beta 0.022, 41 x 41 states in "
          f"{time.perf_counter() - started:.1f} s: " + ", ".join(
              f"{a.name} {100 * a.basin_fraction:.1f} %" for a in basin_map.attractors))
    figure = plot_basins(basin_map, title="case (g), beta = 0.022: basins of attraction")
    figure.set_dpi(DPI)
    figure.savefig(figures / "basins_case_g.png", format="png", dpi=DPI)


def search_orbits(beta: float = 0.022, max_period: int = 8) -> None:
    """Distinct periodic orbits from Newton's method started at transients' close returns."""
    model = case_g(beta)
    rng = np.random.default_rng(1)
    starts = np.column_stack([rng.uniform(-0.5, 0.0, 200), rng.uniform(-10.0, 10.0, 200)])
    runs = run_poincare(np.tile(model.pack(), (starts.shape[0], 1)), starts,
                        PoincareSettings(0, 60))
    rate = 2 * np.pi * model.drive.frequency_hz
    states = np.stack([runs.theta, runs.theta_dot / rate], axis=-1)
    once = PeriodMap(model, "beta", 1)
    started = time.perf_counter()
    print(f"periodic orbits of case (g) at beta {beta}, Newton from close returns of "
          f"{starts.shape[0]} transients:")
    for k in range(1, max_period + 1):
        returns = np.argwhere(np.abs(states[:, k:] - states[:, :-k]).max(axis=-1) < 0.01)
        rng.shuffle(returns)
        period_map, found = PeriodMap(model, "beta", k), []
        for run, n in returns[:150]:
            guess = np.array([runs.theta[run, n], runs.theta_dot[run, n]])
            try:
                orbit = find_periodic_orbit(period_map, beta, guess)
            except ShootingError:
                continue
            points = [orbit.state]
            for _ in range(k - 1):
                points.append(once.images(beta, points[-1])[0])
            points = np.array(points)
            if any(np.abs(points[j] - points[0]).max() < 1e-6 for j in range(1, k)):
                continue  # a shorter period
            if any(np.abs(other - points[0]).max(axis=1).min() < 1e-6 for other, _ in found):
                continue  # an orbit found before
            found.append((points, orbit.multipliers))
        print(f"  k = {k}: {len(returns)} close returns, {len(found)} orbit(s) of period {k}")
        for points, multipliers in found:
            stable = "stable" if np.all(np.abs(multipliers) < 1) else "unstable"
            print(f"    (theta, theta') = ({points[0, 0]:.5f}, {points[0, 1]:.5f}), "
                  f"multipliers {np.round(multipliers, 4).tolist()}, {stable}")
    print(f"  search: {time.perf_counter() - started:.1f} s")


def ten_hz(figures: Path, work: Path) -> None:
    """The period-2 orbit of the 10 Hz case over beta 0.01..0.13 over a recorded sweep."""
    sweep = work / "sweep_10hz.h5"
    if not sweep.exists():
        L_m = load_config().constants.L_m
        print("recording the demo's 10 Hz sweep on the virtual rig (about 2 minutes) ...")
        code = rig_main(["sweep", "--sim", "--sweep", "amplitude", "--start",
                         f"{SWEEP_BETAS[0] * L_m * 1e3:.6g}", "--stop",
                         f"{SWEEP_BETAS[-1] * L_m * 1e3:.6g}", "--steps", str(len(SWEEP_BETAS)),
                         "--drive-hz", "10", "--settle", "3", "--dwell", "5", "--out",
                         str(sweep), "--quiet"])
        if code:
            raise SystemExit(f"the sweep failed ({code})")
    out = work / "ten_hz.h5"
    parser = argparse.ArgumentParser(prog="impact-rig")
    continuation.register(parser.add_subparsers(dest="command"))
    for command in parser._subparsers._group_actions[0].choices.values():
        add_common_options(command)
    args = parser.parse_args(["continue", "--case", "g", "--vary", "beta=0.01:0.13",
                              "--period", "2", "--brute-force", "120", "--overlay", str(sweep),
                              "--out", str(out), "--overwrite", "--quiet"])
    started = time.perf_counter()
    args.func(args)
    print(f"  (the command took {time.perf_counter() - started:.1f} s)")
    shutil.copyfile(out.with_suffix(".png"), figures / "continuation_10hz.png")


def settled_state(model: Model, periods: int = 2000) -> np.ndarray:
    """(theta, theta') at drive phase 0 after ``periods`` drive periods from rest (where
    ``impact-rig continue`` starts without --from-state)."""
    period_s = 1.0 / model.drive.frequency_hz
    run = simulate(model, 0.0, 0.0, settings=SimulationSettings(
        duration_s=period_s, fs_hz=1.0 / period_s, skip_s=periods * period_s))
    return np.array([run.poincare.theta[-1], run.poincare.theta_dot[-1]])


def compare_jacobians(repeats: int) -> list[dict[str, str]]:
    """The gallery's continuations with each Jacobian method: events and CPU time per point."""
    model = case_g(0.01)
    cases = [("case (g), period 1, beta 0.01..0.04", 1, 0.04, np.array((-0.012, -0.73)), 4),
             ("case (g), period 2, beta 0.01..0.04", 2, 0.04, np.array((-0.028, -1.44)), 4),
             ("10 Hz, period 2, beta 0.01..0.13", 2, 0.13, settled_state(model), 8)]
    methods = ("sensitivities", "differences")
    for method in methods:  # compile and warm both before timing either
        continue_orbits(PeriodMap(model, "beta", 1, jacobians=method), 0.01, 0.011,
                        cases[0][3], max_periods=1)
    rows, total = [], {m: [0.0, 0] for m in methods}
    for name, periods, stop, guess, max_periods in cases:
        best: dict[str, float] = {}
        found: dict[str, ContinuationResult] = {}
        for _ in range(repeats):
            for method in methods:
                started = time.process_time()
                outcome = continue_orbits(PeriodMap(model, "beta", periods, jacobians=method),
                                          0.01, stop, guess, max_periods=max_periods)
                cpu = (time.process_time() - started) / outcome.points
                best[method] = min(best.get(method, np.inf), cpu)
                found[method] = outcome
        for method in methods:
            total[method][0] += best[method] * found[method].points
            total[method][1] += found[method].points
            report(found[method], f"{name}, {method} ({found[method].jacobians})")
            print(f"  CPU time {1e3 * best[method]:.2f} ms per point (best of {repeats})")
        same, shift, ends, only = _matched_events(found["sensitivities"], found["differences"])
        ratio = best["differences"] / best["sensitivities"]
        print(f"{name}: {same} events found by both, largest difference {shift:.2g} in beta "
              f"(bracket ends {ends:.2g}); {'; '.join(only) or 'no event found by one only'}; "
              f"differences / sensitivities per point: {ratio:.2f}x")
        rows.append(figure(
            f"continuation, {name}: CPU ms per point, sensitivities / central differences "
            f"(ratio); events found by both, their largest difference",
            f"{1e3 * best['sensitivities']:.2f} / {1e3 * best['differences']:.2f} "
            f"({ratio:.2f}x); {same}, {shift:.2g}" + (f"; {'; '.join(only)}" if only else ""),
            ">= 2x"))
    per_point = {m: total[m][0] / total[m][1] for m in methods}
    ratio = per_point["differences"] / per_point["sensitivities"]
    print(f"all three: {1e3 * per_point['sensitivities']:.2f} ms per point with the "
          f"sensitivities, {1e3 * per_point['differences']:.2f} ms with central differences: "
          f"{ratio:.2f}x")
    rows.append(figure("continuation, the three above: CPU ms per point, sensitivities / "
                       "central differences (ratio)",
                       f"{1e3 * per_point['sensitivities']:.2f} / "
                       f"{1e3 * per_point['differences']:.2f} ({ratio:.2f}x)", ">= 2x"))
    return rows


def _matched_events(a: ContinuationResult, b: ContinuationResult):
    """Events of ``a`` and ``b`` paired in order by kind and period: how many pair, the
    largest difference of their values and of their brackets' ends, and what only one found."""
    def keyed(result: ContinuationResult) -> dict[tuple[str, int], list[float]]:
        events: dict[tuple[str, int], list] = {}
        for event in result.events:
            events.setdefault((event.kind, event.periods), []).append(event)
        return events

    left, right = keyed(a), keyed(b)
    same, shift, ends, only = 0, 0.0, 0.0, []
    for key in sorted(set(left) | set(right)):
        mine, theirs = left.get(key, []), right.get(key, [])
        for x, y in zip(mine, theirs, strict=False):
            located = [np.all(np.isfinite(e.bracket)) for e in (x, y)]
            if not all(located):  # a branch stopped short of it: recorded, not located
                only.append(f"{x.kind} (period {x.periods}) at {x.value:.9g} / {y.value:.9g}: "
                            f"not located by the "
                            f"{'sensitivities' if not located[0] else 'differences'}")
                continue
            same += 1
            shift = max(shift, abs(x.value - y.value))
            ends = max(ends, *(abs(p - q) for p, q in zip(x.bracket, y.bracket, strict=True)))
        for extra, who in ((mine[len(theirs):], "sensitivities"),
                           (theirs[len(mine):], "differences")):
            only += [f"{event.kind} (period {event.periods}) at {event.value:.9g} by the "
                     f"{who} only" for event in extra]
    return same, shift, ends, only


def main() -> int:
    """Regenerate the gallery's figures and print what they show."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--figures", type=Path, default=Path("docs/figures"))
    parser.add_argument("--work", type=Path, default=Path("continuation_gallery"),
                        help="folder for the sweep recording and the command's own output")
    parser.add_argument("--compare-jacobians", action="store_true",
                        help="only compare the continuations' Jacobian methods (no figures)")
    parser.add_argument("--repeats", type=int, default=2,
                        help="with --compare-jacobians: runs of each method, the best counts")
    parser.add_argument("--save", action="store_true", help="with --compare-jacobians: also "
                        "write the figures to benchmarks/results/continuation.json")
    args = parser.parse_args()
    if args.compare_jacobians:
        load = os.getloadavg()[0]
        rows = compare_jacobians(args.repeats)
        if args.save:
            save(result("continuation", rows, load_at_start=load))
        return 0
    args.figures.mkdir(parents=True, exist_ok=True)
    args.work.mkdir(parents=True, exist_ok=True)
    gallery_case_g(args.figures)
    basins_case_g(args.figures)
    search_orbits()
    ten_hz(args.figures, args.work)
    for name in ("continuation_case_g", "basins_case_g", "continuation_10hz"):
        size = (args.figures / f"{name}.png").stat().st_size
        print(f"{args.figures / name}.png: {size / 1e3:.0f} kB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
