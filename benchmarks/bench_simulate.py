"""Simulator speed against scipy's solve_ivp at equal accuracy, measured in the same run.

Baseline: ``scipy.integrate.solve_ivp`` (DOP853) with a terminal event on the contact
surface, restarted at each event in the region's right-hand side (the same compiled
``analysis.model.acceleration``), samples from its dense output.  Both integrators are
compared with a tight-tolerance reference (solve_ivp at rtol 1e-13) on a 1 kHz grid;
the baseline runs at rtol 1e-9 and our simulator at the loosest tolerance of a ladder
whose error is not larger, so the ratio compares equal (or better) accuracy.  The
same is repeated at moderate accuracy (baseline rtol 1e-6).

Scenarios: (1) the paper's case h, 200 drive periods; (2) impact decay released at
-1.2 rad, 12 s (to rest within the sensor's resolution).  Last, the streaming Stepper's
real-time factor at 200 kHz output (the virtual rig's need: > 1).

    python -m benchmarks.bench_simulate          (or python benchmarks/bench_simulate.py)
    python benchmarks/bench_simulate.py --save   (also benchmarks/results/simulate.json)

The machine may be shared: timings are CPU times (time.process_time), the best of
several repetitions.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from analysis.model import Model, acceleration, paper_case  # noqa: E402
from analysis.packed import P  # noqa: E402
from analysis.simulate import SimulationSettings, Stepper, simulate_packed  # noqa: E402
from harness.results import figure, result, save  # noqa: E402

GRID_HZ = 1000.0
BASELINE_RTOL = 1e-9
MODERATE_RTOL = 1e-6
OUR_RTOLS = tuple(10.0 ** (-k / 2) for k in range(10, 25))  # 1e-5 ... 1e-12


def solve_ivp_with_events(
    p: np.ndarray, theta0: float, theta_dot0: float, t_end: float, grid: np.ndarray, rtol: float
) -> tuple[np.ndarray, int]:
    """The baseline: DOP853 between contact-surface events; returns theta on ``grid``, steps."""
    p_free = p.copy()
    p_free[P.BARRIER] = 0.0
    theta_b = p[P.THETA_B]
    theta = np.full(grid.size, np.nan)
    t, y, contact, steps = 0.0, np.array([theta0, theta_dot0]), theta0 > theta_b, 0

    def surface(t, y):
        return y[0] - theta_b

    surface.terminal = True
    while t < t_end:
        pr = p if contact else p_free
        surface.direction = -1.0 if contact else 1.0
        sol = solve_ivp(
            lambda t, y, pr=pr: (y[1], acceleration(t, y[0], y[1], pr)),
            (t, t_end),
            y,
            method="DOP853",
            rtol=rtol,
            atol=rtol * 1e-2,
            events=surface,
            dense_output=True,
        )
        steps += sol.t.size - 1
        inside = (grid >= t) & (grid <= sol.t[-1])
        if inside.any() and sol.t.size > 1:
            theta[inside] = sol.sol(grid[inside])[0]
        if sol.status != 1:
            break
        t, y, contact = sol.t_events[0][0], sol.y_events[0][0], not contact
    return theta, steps


def _best_time(function, repeats: int) -> tuple[float, object]:
    """Smallest CPU time of ``repeats`` calls (CPU, not wall: the machine may be shared)."""
    best, value = math.inf, None
    for _ in range(repeats):
        started = time.process_time()
        value = function()
        best = min(best, time.process_time() - started)
    return best, value


def scenario(
    name: str, model: Model, theta0: float, duration_s: float, baseline_rtol: float
) -> tuple[float, float]:
    """Print errors, speeds and the ratio for one scenario; returns the ratio and our CPU
    seconds per run."""
    p = model.pack()
    grid = np.arange(math.floor(duration_s * GRID_HZ)) / GRID_HZ
    reference, _ = solve_ivp_with_events(p, theta0, 0.0, duration_s, grid, 1e-13)
    baseline_time, (baseline, baseline_steps) = _best_time(
        lambda: solve_ivp_with_events(p, theta0, 0.0, duration_s, grid, baseline_rtol), 3
    )
    baseline_error = np.abs(baseline - reference).max()

    def ours(rtol: float):
        return simulate_packed(
            p, theta0, 0.0,
            settings=SimulationSettings(
                duration_s=duration_s, fs_hz=GRID_HZ, poincare_phase=None, rtol=rtol,
                atol=rtol * 1e-2,
            ),
        )

    ours(1e-9)  # compile / load the cache outside the timing
    chosen = None
    for rtol in OUR_RTOLS:
        result = ours(rtol)
        error = np.abs(result.theta - reference).max()
        if error <= baseline_error:
            chosen = (rtol, error)
            break
    if chosen is None:
        raise RuntimeError(f"{name}: no tolerance of {OUR_RTOLS} reaches {baseline_error:.2e}")
    rtol, error = chosen
    our_time, result = _best_time(lambda: ours(rtol), 20)
    ratio = baseline_time / our_time
    print(f"# {name}: max error vs reference on a {GRID_HZ:g} Hz grid, CPU times")
    print(
        f"#   solve_ivp DOP853 rtol {baseline_rtol:.0e}: error {baseline_error:.2e} rad, "
        f"{baseline_time * 1e3:.1f} ms, {baseline_steps} steps"
    )
    print(
        f"#   analysis.simulate rtol {rtol:.0e}: error {error:.2e} rad, {our_time * 1e3:.2f} ms, "
        f"{result.n_steps} steps, {result.contacts.count} contacts"
    )
    print(f"steps_per_second {name} solve_ivp {baseline_steps / baseline_time:.3g}")
    print(f"steps_per_second {name} analysis.simulate {result.n_steps / our_time:.3g}")
    print(f"speedup_vs_solve_ivp {name} {ratio:.0f}")
    return ratio, our_time


def stepper_real_time(model: Model, seconds: float = 5.0, fs_hz: float = 200_000.0) -> float:
    """Simulated seconds per CPU second of the streaming Stepper at 200 kHz in 10 ms chunks."""
    chunk = int(fs_hz / 100)
    stepper = Stepper(model, -0.2)
    stepper.advance(np.arange(1, chunk + 1) / fs_hz)  # compile / load outside the timing
    started = time.process_time()
    for k in range(1, int(seconds * 100)):
        stepper.advance((k * chunk + np.arange(1, chunk + 1)) / fs_hz)
    factor = seconds / (time.process_time() - started)
    print(f"stepper_real_time_factor case_h_200kHz {factor:.0f}")
    return factor


def main() -> None:
    """Run both scenarios and the streaming check."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/simulate.json")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    rig, drive = paper_case("h").dimensional()
    case_h = (Model(rig, drive), -0.2, 200.0 / drive.frequency_hz)
    impact_decay = (Model(), -1.2, 12.0)
    h = scenario("case_h_200_periods", *case_h, BASELINE_RTOL)
    decay = scenario("impact_decay_from_-1.2_rad", *impact_decay, BASELINE_RTOL)
    print("# the same at moderate accuracy (solve_ivp at rtol 1e-6)")
    h_moderate, _ = scenario("case_h_200_periods@moderate", *case_h, MODERATE_RTOL)
    decay_moderate, _ = scenario("impact_decay_from_-1.2_rad@moderate", *impact_decay,
                                 MODERATE_RTOL)
    print("# streaming: simulated seconds per CPU second, 200 kHz samples in 10 ms chunks")
    factor = stepper_real_time(case_h[0])
    if args.save:
        save(result("simulate", [
            figure("compiled integrator vs `solve_ivp` DOP853 (restarted at each contact) at "
                   "equal accuracy, paper case h over 200 periods",
                   f"{h[0]:.0f}x ({h[1] * 1e3:.2f} ms per run)"),
            figure("the same, impact decay from -1.2 rad",
                   f"{decay[0]:.0f}x ({decay[1] * 1e3:.2f} ms per run)"),
            figure("the same at moderate accuracy (case h / decay)",
                   f"{h_moderate:.0f}x / {decay_moderate:.0f}x"),
            figure("Stepper at 200 kHz", f"{factor:.0f}x real time"),
        ], load_at_start=load))


if __name__ == "__main__":
    main()
