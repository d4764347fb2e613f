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
    python benchmarks/bench_regime.py --save   (also benchmarks/results/regime.json)
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
    classify_regime,
    judge_record_regime,
    poincare_from_pulses,
)
from analysis.model import Drive, Model, RigParameters, paper_case  # noqa: E402
from analysis.simulate import SimulationSettings, simulate  # noqa: E402
from hardware_sim.virtual_rig import VirtualRig, VirtualRigSettings  # noqa: E402
from harness.results import figure, result, save  # noqa: E402
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


def bench_records() -> list[tuple[str, bool, bool, float]]:
    """Judge each record; per record its name, whether ``judge_record_regime`` and the former
    ``classify_regime`` named its regime, and the best time of the first."""
    rng = np.random.default_rng(2024)
    records = [(kind, analytic(kind, rng), 10.0, kind.split()[0]) for kind in (
        "period-1", "period-2", "period-5", "period-32", "period-2 settling", "quasi-periodic"
    )]
    for case, expected in (("a", "period-1"), ("g", "period-2"), ("i", "chaotic")):
        theta, drive_hz = simulated(case)
        records.append((f"paper case {case} ({expected})", theta, drive_hz, expected))
    judge_record_regime(records[0][1], FS, NOISE_RAD, frequency_hz=10.0)  # load numba caches
    print(f"judge_record_regime on {SECONDS:g} s at {FS:g} Hz, noise {NOISE_RAD * 1e3:g} mrad")
    print(f"  {'record':32s} {'judged':16s} {'s':>6s}   {'classify_regime':16s} {'s':>6s}")
    judged = []
    for name, theta, drive_hz, expected in records:
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
        judged.append((name, regime.short_name == expected, former.short_name == expected,
                       seconds))
    return judged


def bench_demo_sweep() -> tuple[list[tuple[float, str]], float]:
    """Judge the demo's sweep step by step; the verdict per beta and the seconds in all."""
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
    total, verdicts = 0.0, []
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
        verdicts.append((beta, regime.short_name))
    print(f"  {total:.2f} s for {len(betas)} steps")
    return verdicts, total


def sweep_summary(verdicts: list[tuple[float, str]]) -> str:
    """The sweep's verdicts by regime, in order of beta: 'period-2 at beta 0.02-0.095, ...'."""
    by_regime: dict[str, list[float]] = {}
    for beta, name in sorted(verdicts):
        by_regime.setdefault(name, []).append(beta)
    return ", ".join(
        f"{name} at beta {betas[0]:g}" + (f"-{betas[-1]:g}" if betas[-1] != betas[0] else "")
        + (f" ({len(set(betas))} betas)" if len(set(betas)) > 2 else "")
        for name, betas in by_regime.items()
    )


def main() -> None:
    """Judge the records and the demo's sweep (and with --save write the figures)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/regime.json")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    judged = bench_records()
    verdicts, total = bench_demo_sweep()
    if not args.save:
        return
    right = sum(ours for _, ours, _, _ in judged)
    former = sum(theirs for _, _, theirs, _ in judged)
    seconds = [time for *_, time in judged]
    slowest = [name for name, *_ in sorted(judged, key=lambda row: -row[3])[:3]]
    save(result("regime", [
        figure("regime of forced records (60 s at 1 kHz, 1 mrad noise, a tach with missing, "
               "doubled and spurious pulses: period 1, 2, 5, 32, a settling period 2, "
               "quasi-periodic, paper cases a, g, i) judged right",
               f"{right}/{len(judged)} (the former `classify_regime` on the tach Poincare "
               f"section: {former}/{len(judged)})"),
        figure("time per record", f"{min(seconds):.2f}-{max(seconds):.2f} s (most for "
               f"{', '.join(slowest)})"),
        figure(f"the demo's sweep on the virtual rig, {len(verdicts)} steps",
               f"{sweep_summary(verdicts)}; {total:.2f} s"),
    ], load_at_start=load))


if __name__ == "__main__":
    main()
