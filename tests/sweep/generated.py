"""A small seeded sweep from the independent reference simulator (scipy; never the
project's integrator or virtual rig), for the shared fit's tests: one rig, the drive's
amplitude stepped up, each step settled and dwelt on, the motion continued from step to
step as a rig runs it; written as a real recording with its sweep steps."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from reference.forced_records import RigTruth, quantise, tach_pulses
from reference.simulator import Pendulum, TableMotion, simulate_reference
from rig.events import StepMark
from tests.sweep.recordings import write_sweep_recording

RIG = RigTruth(m_kg=0.0326, l_m=0.05, L_m=0.048, R_m=0.0095, g_m_s2=9.81, zeta=0.008,
               E_Pa=2.0e6, mu0_s_per_m=0.8)
ANGLE_STEP_RAD = math.pi / 2**16


@dataclass(frozen=True)
class SweepTruth:
    """What the generated sweep hides: the rig, the barrier, the settings."""

    rig: RigTruth
    theta_b_rad: float
    frequency_hz: float
    amplitudes_m: tuple[float, ...]
    noise_rad: float


def generate_sweep(
    path: Path, *, seed: int, theta_b_rad: float = 0.0, frequency_hz: float = 10.0,
    betas: tuple[float, ...] = (0.02, 0.03, 0.04), settle_s: float = 2.0,
    dwell_s: float = 5.0, fs: float = 500.0, noise_rad: float = 1e-3,
    interrupted_at: int | None = None,
) -> SweepTruth:
    """Simulate the sweep and write it to ``path`` as a recording (angle, table, tach and
    its step marks); ``interrupted_at``: the sweep stops half way through that step."""
    rng = np.random.default_rng(seed)
    pendulum = Pendulum(m_kg=RIG.m_kg, l_m=RIG.l_m, L_m=RIG.L_m, zeta=RIG.zeta,
                        K_n=RIG.K_N_per_m1_5, mu0_s_per_m=RIG.mu0_s_per_m,
                        g_m_s2=RIG.g_m_s2, theta_b_rad=theta_b_rad)
    phase0 = float(rng.uniform(0.0, 2.0 * math.pi))
    amplitudes = tuple(round(b * RIG.L_m, 6) for b in betas)
    per_step = round((settle_s + dwell_s) * fs)
    state = np.array([-0.05, 0.0])
    angles, tables, tachs, marks = [], [], [], []
    for k, amplitude in enumerate(amplitudes):
        first = k * per_step
        n = per_step if interrupted_at != k else per_step // 2
        t = (first + np.arange(n)) / fs
        table = TableMotion(amplitude, frequency_hz, phase0)
        run = simulate_reference(pendulum, table, state[0], state[1], t, t_start_s=t[0],
                                 t_end_s=(first + per_step) / fs)
        state = run.final_state[:2]
        angles.append(quantise(run.theta_rad + rng.normal(0.0, noise_rad, n), ANGLE_STEP_RAD))
        tables.append(quantise(table.displacement(t) + rng.normal(0.0, 1e-5, n), 1e-6))
        tachs.append(first + np.flatnonzero(tach_pulses(t, table)))
        marks.append(StepMark(k, 1, frequency_hz, amplitude, first,
                              first + round(settle_s * fs), first + per_step,
                              interrupted_at != k))
        if interrupted_at == k:
            break
    write_sweep_recording(path, np.concatenate(angles), fs, np.concatenate(tachs), marks,
                          table=np.concatenate(tables))
    return SweepTruth(RIG, theta_b_rad, frequency_hz, amplitudes[:len(marks)], noise_rad)
