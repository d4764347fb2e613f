"""What the forward sensitivities of a run cost, against plain runs of the same model, measured
in the same process.

A run's derivatives with respect to its initial state and to k packed parameters by
differences cost k + 2 plain runs (forward differences; twice that central); the
sensitivities (``analysis.simulate.sensitivity``) cost one plain run and the variational
equations carried along its steps.  Scenarios: the paper's case h over 200 drive periods
(one long run, 1 kHz samples) and 40 shooting segments of 0.5 s of case d
(``segment_sensitivities``, 1 kHz samples), each with 0, 2 and 8 parameter columns.

    python benchmarks/bench_sensitivity.py          (prints the figures)
    python benchmarks/bench_sensitivity.py --save   (also benchmarks/results/sensitivity.json)

The machine may be shared: timings are CPU times (time.process_time), the best of several
repetitions, and the figures are ratios to the plain run measured beside them.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from analysis.model import Model, paper_case  # noqa: E402
from analysis.simulate import (  # noqa: E402
    SensitivitySettings,
    SimulationSettings,
    simulate_packed,
    simulate_sensitivities,
)
from analysis.simulate.segments import integrate_segments  # noqa: E402
from analysis.simulate.sensitivity import segment_sensitivities  # noqa: E402
from harness.results import figure, result, save  # noqa: E402

COLUMNS = {
    0: (),
    2: ("K", "MU0"),
    8: ("OMEGA2", "TWO_ZETA_OMEGA", "CONTACT_GAIN", "K", "MU0", "THETA_B", "PHASE0", "A1"),
}
RTOL = 1e-8
REPEATS = 7


def best_cpu_s(run: Callable[[], object]) -> float:
    """The smallest CPU time of REPEATS calls (after one to compile and warm)."""
    run()
    best = float("inf")
    for _ in range(REPEATS):
        start = time.process_time()
        run()
        best = min(best, time.process_time() - start)
    return best


def long_run() -> dict[int, float]:
    """Case h, 200 periods: sensitivities' CPU time over a plain run's, per column count."""
    rig, drive = paper_case("h").dimensional()
    p = Model(rig, drive).pack()
    t = np.arange(1, int(200.0 / drive.frequency_hz * 1000.0) + 1) * 1e-3
    settings = SimulationSettings(duration_s=float(t[-1]), fs_hz=1000.0, poincare_phase=None,
                                  rtol=RTOL, atol=RTOL * 1e-2)
    alone = best_cpu_s(lambda: simulate_packed(p, -0.2, 0.0, settings=settings))
    ratios = {}
    for count, names in COLUMNS.items():
        chosen = SensitivitySettings(parameters=names, rtol=RTOL, atol=RTOL * 1e-2)
        ratios[count] = best_cpu_s(
            lambda chosen=chosen: simulate_sensitivities(p, -0.2, 0.0, t, settings=chosen)
        ) / alone
    return ratios


def segments() -> dict[int, float]:
    """40 segments of 0.5 s of case d: the same ratios against ``integrate_segments``."""
    rig, drive = paper_case("d").dimensional()
    p = Model(rig, drive).pack()
    n = 40
    t0 = np.arange(n) * 0.5
    state0 = np.column_stack([np.full(n, -0.3), np.zeros(n)])
    out_t = np.concatenate([t0[k] + np.arange(1, 501) * 1e-3 for k in range(n)])
    bounds = np.arange(n + 1) * 500
    alone = best_cpu_s(lambda: integrate_segments(p, t0, state0, out_t, bounds, rtol=RTOL,
                                                  atol=RTOL * 1e-2))
    ratios = {}
    for count, names in COLUMNS.items():
        chosen = SensitivitySettings(parameters=names, rtol=RTOL, atol=RTOL * 1e-2)
        ratios[count] = best_cpu_s(
            lambda chosen=chosen: segment_sensitivities(p, t0, state0, out_t, bounds,
                                                        settings=chosen)
        ) / alone
    return ratios


def main() -> None:
    """Measure both scenarios and print (and with --save write) the ratios."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/sensitivity.json")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    rows = []
    for name, ratios in (("case h, 200 periods", long_run()),
                         ("40 segments of case d", segments())):
        for count, ratio in ratios.items():
            print(f"{name}: sensitivities with {count} parameter columns cost {ratio:.1f} plain "
                  f"runs (differences: {count + 2})")
        rows.append(figure(
            f"sensitivities of the initial state and 0 / 2 / 8 parameters, in plain runs "
            f"({name}; forward differences: 2 / 4 / 10)",
            " / ".join(f"{ratios[count]:.1f}" for count in sorted(ratios))))
    if args.save:
        save(result("sensitivity", rows, load_at_start=load))


if __name__ == "__main__":
    main()
