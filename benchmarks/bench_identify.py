"""Identification speed and statistics: impact-decay fit time, interval coverage and bias.

1. Time of a full impact-decay fit (K, mu0, theta_b, L, zeta, initial state, offset)
   on a 10 s record at 10 kHz; goal under 10 s on 2 cores.  Baseline measured in the
   same run: one simulation of that record, so the ratio says how many simulations
   the fit costs.
2. Coverage of the 95 % intervals and bias over many seeded trials: free decays
   (averaging and full-simulation fits, data from scipy's DOP853, an independent
   integrator) and impact decays (data from the project's simulator).

    python benchmarks/bench_identify.py --trials 100
    python benchmarks/bench_identify.py --save      (also benchmarks/results/identify.json)
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

from analysis.identify import fit_free_decay, fit_impact_decay  # noqa: E402
from analysis.model import Model, RigParameters  # noqa: E402
from analysis.records import Record  # noqa: E402
from analysis.simulate import SimulationSettings, simulate  # noqa: E402
from harness.results import figure, result, save  # noqa: E402
from reference.oracle import free_decay  # noqa: E402

RIG_KEYS = {"m_kg": 0.0326, "l_m": 0.05, "R_m": 0.0095, "g": 9.81}


def _impact_truth(rng: np.random.Generator) -> tuple[RigParameters, float, float]:
    truth = RigParameters(
        L_m=float(rng.uniform(0.055, 0.1)),
        zeta=float(rng.uniform(0.002, 0.006)),
        mu0_s_per_m=float(rng.uniform(0.2, 1.5)),
        theta_b_rad=float(rng.uniform(-0.02, 0.02)),
    ).with_stiffness(float(10 ** rng.uniform(5.0, 6.0)))
    return truth, float(rng.uniform(-0.4, -0.25)), float(rng.uniform(-0.01, 0.01))


def _impact_record(rng, truth, theta0, offset, duration_s, fs_hz) -> Record:
    sim = simulate(
        Model(rig=truth, barrier=True), theta0, 0.0,
        settings=SimulationSettings(duration_s=duration_s, fs_hz=fs_hz, poincare_phase=None),
    )
    angle = sim.theta + offset + rng.normal(0.0, 2e-4, sim.t.size)
    return Record(sim.t, angle, "impact_decay", rig=RIG_KEYS)


def bench_impact_fit_time(repeats: int) -> float:
    rng = np.random.default_rng(10)
    truth, theta0, offset = _impact_truth(rng)
    record = _impact_record(rng, truth, theta0, offset, 10.0, 10_000.0)
    fit_impact_decay(record)  # compile and warm up
    sim_times, fit_times = [], []
    for _ in range(repeats):
        start = time.perf_counter()
        simulate(
            Model(rig=truth, barrier=True), theta0, 0.0,
            settings=SimulationSettings(duration_s=10.0, fs_hz=10_000.0, poincare_phase=None),
        )
        sim_times.append(time.perf_counter() - start)
        start = time.perf_counter()
        result = fit_impact_decay(record)
        fit_times.append(time.perf_counter() - start)
    fit, sim = min(fit_times), min(sim_times)
    print("impact-decay fit, 10 s at 10 kHz (100 000 samples), 8 parameters free:")
    print(f"  fit {fit:.2f} s (goal < 10 s), one simulation {sim * 1e3:.1f} ms, "
          f"ratio {fit / sim:.0f} simulations per fit")
    K = result["K_N_per_m1.5"]
    print(f"  K {K.value:.5g} (true {truth.K_N_per_m1_5:.5g}), mu0 "
          f"{result['mu0_s_per_m'].value:.4g} (true {truth.mu0_s_per_m:.4g})")
    return fit


def _report(name: str, key: str, truths: list[float], results: list) -> float:
    """Print the coverage, bias and z statistics of one parameter; returns the coverage."""
    truths_a = np.array(truths)
    values = np.array([r[key].value for r in results])
    half = np.array([r[key].half_width for r in results])
    covered = np.sum(np.abs(values - truths_a) <= half)
    z = (values - truths_a) / (half / 1.959963984540054)
    rel = values / truths_a - 1.0
    print(f"  {name:<14} {key:<14} coverage {covered}/{len(truths)} "
          f"({100 * covered / len(truths):.0f} %), bias {np.mean(rel):+.2e} relative "
          f"(+-{np.std(rel) / math.sqrt(len(rel)):.1e}), z mean {np.mean(z):+.2f} "
          f"sd {np.std(z):.2f}")
    return float(covered / len(truths))


def bench_free_decay_coverage(
    trials: int, amplitude: tuple[float, float], name: str
) -> dict[str, float]:
    rng = np.random.default_rng(123 if name == "averaging" else 321)
    truths: dict[str, list[float]] = {"L_m": [], "zeta": []}
    results = []
    start = time.perf_counter()
    for _ in range(trials):
        L, zeta = rng.uniform(0.12, 0.6), rng.uniform(0.012, 0.04)
        theta0 = rng.uniform(*amplitude) * rng.choice([-1.0, 1.0])
        t, theta = free_decay(theta0, zeta, L, duration_s=12.0, fs_hz=400.0)
        measured = theta + rng.uniform(-0.05, 0.05) + rng.normal(0.0, 1e-3, t.size)
        results.append(fit_free_decay(Record(t, measured, "free_decay")))
        truths["L_m"].append(L)
        truths["zeta"].append(zeta)
    elapsed = time.perf_counter() - start
    print(f"free decay, {name} fits, {trials} trials, amplitude {amplitude} rad "
          f"({elapsed / trials:.2f} s per fit):")
    return {key: _report(name, key, truths[key], results) for key in ("L_m", "zeta")}


def bench_impact_coverage(trials: int) -> dict[str, float]:
    rng = np.random.default_rng(77)
    truths: dict[str, list[float]] = {"K_N_per_m1.5": [], "mu0_s_per_m": []}
    results = []
    start = time.perf_counter()
    for _ in range(trials):
        truth, theta0, offset = _impact_truth(rng)
        record = _impact_record(rng, truth, theta0, offset, 6.0, 5000.0)
        results.append(fit_impact_decay(record))
        truths["K_N_per_m1.5"].append(truth.K_N_per_m1_5)
        truths["mu0_s_per_m"].append(truth.mu0_s_per_m)
    elapsed = time.perf_counter() - start
    print(f"impact decay, {trials} trials, 6 s at 5 kHz ({elapsed / trials:.2f} s per fit):")
    return {key: _report("impact", key, truths[key], results) for key in truths}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=100, help="free-decay trials (averaging)")
    parser.add_argument("--repeats", type=int, default=3, help="timing repeats (best is shown)")
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/identify.json")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    fit_s = bench_impact_fit_time(args.repeats)
    free = bench_free_decay_coverage(args.trials, (0.05, 0.18), "averaging")
    bench_free_decay_coverage(max(5, args.trials // 4), (0.3, 1.5), "simulation")
    impact_trials = max(5, args.trials // 5)
    impact = bench_impact_coverage(impact_trials)
    if args.save:
        coverage = [free["L_m"], free["zeta"], impact["K_N_per_m1.5"], impact["mu0_s_per_m"]]
        save(result("identify", [
            figure("time to fit a 10 s impact decay at 10 kHz", f"{fit_s:.2f} s", "< 10 s"),
            figure(f"95 % intervals' coverage of L, zeta, K, mu0 ({args.trials}/{args.trials}/"
                   f"{impact_trials}/{impact_trials} trials)",
                   ", ".join(f"{100 * value:.0f} %" for value in coverage)),
        ], load_at_start=load))


if __name__ == "__main__":
    main()
