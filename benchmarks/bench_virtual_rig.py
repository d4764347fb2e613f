"""How fast the virtual rig generates DAQ samples, as a multiple of real time at 200 kHz.

Baseline measured in the same run: the bare Stepper integrating the same physics
to the same sample times (no shaker, sensors or quantization), so the ratio is
the cost the rig adds on top of the integrator.

    python benchmarks/bench_virtual_rig.py
    python benchmarks/bench_virtual_rig.py --save   (also benchmarks/results/virtual-rig.json)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from analysis.model import Model, paper_case
from analysis.simulate import Stepper
from hardware_sim.virtual_rig import VirtualRig, VirtualRigSettings
from harness.results import figure, result, save

RATE_HZ = 200_000.0
DURATION_S = 2.0


def _cases() -> dict[str, tuple[Model, float]]:
    rig, drive = paper_case("d").dimensional()
    return {
        "free swing, no barrier": (Model(barrier=False), 0.3),
        "impacts, paper case d (10 Hz)": (Model(rig=rig, drive=drive), 0.1),
    }


def _time_rig(model: Model, theta0: float, block: int) -> float:
    rig = VirtualRig(
        VirtualRigSettings(
            model=model,
            sample_rate_hz=RATE_HZ,
            theta0_rad=theta0,
            angle_noise_rad=2e-4,
            table_noise_m=2e-6,
        )
    )
    rig.generate(block)  # compile / warm up
    n_blocks = int(DURATION_S * RATE_HZ) // block
    start = time.perf_counter()
    for _ in range(n_blocks):
        rig.generate(block)
    return time.perf_counter() - start


def _time_stepper(model: Model, theta0: float, block: int) -> float:
    stepper = Stepper(model, theta0)
    t = 1.0 / RATE_HZ
    stepper.advance(np.arange(1, block + 1) * t)
    n_blocks = int(DURATION_S * RATE_HZ) // block
    start = time.perf_counter()
    first = block + 1
    for _ in range(n_blocks):
        stepper.advance(np.arange(first, first + block) * t)
        first += block
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--save", action="store_true",
                        help="also write the figures to benchmarks/results/virtual-rig.json")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    rig_factors, bare_factors = [], []
    print(f"{DURATION_S:g} s of stream at {RATE_HZ / 1000:g} kHz (angle, table, tach)")
    for name, (model, theta0) in _cases().items():
        for block in (256, 4096):
            rig_s = _time_rig(model, theta0, block)
            bare_s = _time_stepper(model, theta0, block)
            print(
                f"  {name:32s} block {block:5d}: {DURATION_S / rig_s:6.1f}x real time; "
                f"bare Stepper {DURATION_S / bare_s:6.1f}x; rig/Stepper time ratio "
                f"{rig_s / bare_s:4.2f}"
            )
            rig_factors.append(DURATION_S / rig_s)
            bare_factors.append(DURATION_S / bare_s)
    if args.save:
        save(result("virtual-rig", [figure(
            "virtual rig `generate` at 200 kHz vs the bare Stepper",
            f"{min(rig_factors):.0f}-{max(rig_factors):.0f}x faster than real time (bare "
            f"Stepper {min(bare_factors):.0f}-{max(bare_factors):.0f}x)",
        )], load_at_start=load))


if __name__ == "__main__":
    main()
