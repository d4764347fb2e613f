"""Regime judgement of forced records: verdicts and seconds per 60 s record at 1 kHz.

Records of each kind (analytic periodic, settling and quasi-periodic signals; paper
cases a, g and i from the simulator), 1 mrad of noise, tach pulses with a missing, a
doubled and a spurious one.  Each is judged three times by ``judge_record_regime``;
the best time is printed with the verdict.  Baseline, measured in the same run: the
classification of simulated orbits (``classify_regime``, the former demo's) on the
record's Poincare section at the tach pulses, its verdict and time.  Then the demo's
full 10 Hz sweep (8 steps up, 7 down, 8 s dwell after 6 s of settling, 4 kHz) on the
virtual rig, judged step by step.

    python benchmarks/bench_regime.py
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from analysis.dynamics import (  # noqa: E402
    classify_regime,
    judge_record_regime,
    poincare_from_pulses,
)
from analysis.model import Drive, Model, RigParameters, paper_case  # noqa: E402
from analysis.simulate import SimulationSettings, simulate  # noqa: E402
from hardware_sim.virtual_rig import VirtualRig, VirtualRigSettings  # noqa: E402
from rig.demo.settings import FULL  # noqa: E402

FS = 1000.0
SECONDS = 60.0
NOISE_RAD = 1e-3
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def analytic(kind: str, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(int(SECONDS * FS)) / FS
    w = 2 * math.pi * 10.0
    theta = 0.08 * np.sin(w * t + 0.4) + 0.02 * np.sin(2 * w * t + 1.0)
    if kind == "period-2 settling":
        theta += 0.01 * np.sin(0.5 * w * t) + 0.03 * np.exp(-t / 15.0) * np.sin(0.232 * w * t)
    elif kind.startswith("period-"):
        k = int(kind.split("-")[1])
        for m in range(1, k):
            theta += 6e-3 * rng.uniform(0.5, 1.5) * np.sin(m * w * t / k + rng.uniform(0, 6.3))
    elif kind == "quasi-periodic":
        theta += 0.02 * np.sin(GOLDEN * w * t) + 0.01 * np.sin(2 * GOLDEN * w * t + 0.5)
    return theta


def simulated(case: str) -> tuple[np.ndarray, float]:
    rig, drive = paper_case(case).dimensional()
    skip = 10.0 * round(drive.frequency_hz) / drive.frequency_hz
    run = simulate(
        Model(rig, drive), 0.0, 0.0,
        settings=SimulationSettings(duration_s=SECONDS, fs_hz=FS, skip_s=skip),
    )
    return run.theta, drive.frequency_hz


def lab_tach(n: int, drive_hz: float, rng: np.random.Generator) -> np.ndarray:
    pulses = np.rint(np.arange(0.0, n - 1.0, FS / drive_hz)) + rng.integers(-1, 2)
    pulses = np.delete(pulses, 17)
    pulses = np.concatenate([pulses, [pulses[30] + 1, pulses[60] + 0.5 * FS / drive_hz]])
    pulses = np.sort(pulses)
    return pulses[(pulses >= 0) & (pulses < n)]


def best_of(runs: int, call):
    best, result = math.inf, None
    for _ in range(runs):
        start = time.perf_counter()
        result = call()
        best = min(best, time.perf_counter() - start)
    return best, result


def bench_records() -> None:
    rng = np.random.default_rng(2024)
    records = [(kind, analytic(kind, rng), 10.0) for kind in (
        "period-1", "period-2", "period-5", "period-32", "period-2 settling", "quasi-periodic"
    )]
    for case, expected in (("a", "period-1"), ("g", "period-2"), ("i", "chaotic")):
        theta, drive_hz = simulated(case)
        records.append((f"paper case {case} ({expected})", theta, drive_hz))
    judge_record_regime(records[0][1], FS, NOISE_RAD, frequency_hz=10.0)  # load numba caches
    print(f"judge_record_regime on {SECONDS:g} s at {FS:g} Hz, noise {NOISE_RAD * 1e3:g} mrad")
    print(f"  {'record':32s} {'judged':16s} {'s':>6s}   {'classify_regime':16s} {'s':>6s}")
    for name, theta, drive_hz in records:
        noisy = theta + NOISE_RAD * rng.normal(size=theta.size)
        tach = lab_tach(noisy.size, drive_hz, rng)
        seconds, (regime, _) = best_of(3, lambda noisy=noisy, tach=tach, f=drive_hz: (
            judge_record_regime(noisy, FS, NOISE_RAD, tach_indices=tach, frequency_hz=f)
        ))
        baseline, former = best_of(3, lambda noisy=noisy, tach=tach: classify_regime(
            poincare_from_pulses(noisy, FS, np.unique(tach))
        ))
        print(
            f"  {name:32s} {regime.short_name:16s} {seconds:6.3f}   "
            f"{former.short_name:16s} {baseline:6.3f}"
        )


def bench_demo_sweep() -> None:
    rig = RigParameters()
    fs = FULL.sample_rate_hz
    settings = VirtualRigSettings(
        model=Model(rig, Drive()), sample_rate_hz=fs, angle_noise_rad=2e-4, seed=1,
        theta0_rad=-0.005,
    )
    virtual = VirtualRig(settings)
    zero, rad_per_count = settings.angle_counts_to_rad()
    noise_rad = math.hypot(2e-4, rad_per_count / math.sqrt(12.0))
    betas = list(FULL.sweep_betas) + list(FULL.sweep_betas[-2::-1])
    print(f"\nthe full demo's sweep on the virtual rig ({fs:g} Hz, {FULL.dwell_s:g} s dwell)")
    total = 0.0
    for beta in betas:
        virtual.shaker.set_targets(amplitude_m=beta * rig.L_m, frequency_hz=FULL.sweep_frequency_hz)
        virtual.advance(FULL.settle_s)
        samples = virtual.generate(round(FULL.dwell_s * fs))
        angle = (samples["angle"] - zero) * rad_per_count
        tach = np.flatnonzero(samples["tach"])
        start = time.perf_counter()
        regime, _ = judge_record_regime(
            angle, fs, noise_rad, tach_indices=tach, frequency_hz=FULL.sweep_frequency_hz
        )
        total += time.perf_counter() - start
        transient = regime.evidence.get("transient_s")
        before = f"after {transient:.1f} s of transient: " if transient else ""
        print(f"  beta {beta:.3f}: {before}{regime.label[:80]}")
    print(f"  {total:.2f} s for {len(betas)} steps")


if __name__ == "__main__":
    bench_records()
    bench_demo_sweep()
