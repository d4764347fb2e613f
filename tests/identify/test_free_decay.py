"""Free-decay identification against an independent integrator: recovery, coverage, robustness."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from analysis.identify import (
    IdentificationError,
    averaging_solution,
    fit_free_decay,
    pool_free_decays,
)
from analysis.records import Record
from reference.oracle import free_decay
from tests.tolerance import Z_95, Z_999, within_999


def _random_case(rng: np.random.Generator, amplitude: tuple[float, float]) -> dict[str, float]:
    # Drawn well away from the paper's rig (L = 0.046 m, zeta = 0.007).
    return {
        "L_m": float(rng.uniform(0.12, 0.6)),
        "zeta": float(rng.uniform(0.012, 0.04)),
        "theta0": float(rng.uniform(*amplitude)) * rng.choice([-1.0, 1.0]),
        "offset": float(rng.uniform(-0.05, 0.05)),
    }


def _record(case: dict[str, float], rng: np.random.Generator, noise: float = 1e-3,
            duration_s: float = 12.0, fs_hz: float = 400.0) -> Record:
    t, theta = free_decay(case["theta0"], case["zeta"], case["L_m"], duration_s=duration_s,
                          fs_hz=fs_hz)
    measured = theta + case["offset"] + rng.normal(0.0, noise, t.size)
    return Record(t, measured, "free_decay", rig={"g": 9.81})


@pytest.mark.parametrize(("theta0", "zeta"), [(0.1, 0.01), (0.2, 0.005), (0.05, 0.02)])
def test_averaging_solution_matches_the_pendulum_equation_at_small_amplitude(theta0, zeta):
    # Oracle: the numerically integrated pendulum, released from rest.  The averaging
    # solution misses only the third harmonic, theta0^3/192, over many periods; released
    # from rest means amplitude theta0/sqrt(1 - zeta^2) and phase -atan(zeta/sqrt(1 - zeta^2)).
    L = 0.25
    t, theta = free_decay(theta0, zeta, L, duration_s=15.0, fs_hz=200.0)
    omega = math.sqrt(9.81 / L)
    root = math.sqrt(1.0 - zeta**2)
    phase = -math.atan(zeta / root)
    approx = averaging_solution(t, theta0 / root, phase, zeta, omega)
    assert np.max(np.abs(approx - theta)) < 2.5 * theta0**3 / 192
    # ... and without the amplitude-dependent phase drift it would be far worse.
    linear = theta0 / root * np.exp(-zeta * omega * t) * np.cos(omega * root * t + phase)
    assert np.max(np.abs(linear - theta)) > 10 * np.max(np.abs(approx - theta))


def test_small_amplitude_recovery_and_interval_coverage():
    rng = np.random.default_rng(20261122)
    trials, covered_L, covered_zeta, z_L = 10, 0, 0, []
    for _ in range(trials):
        case = _random_case(rng, (0.05, 0.18))
        result = fit_free_decay(_record(case, rng))
        assert result.details["fit_model"] == "averaging solution"
        covered_L += result["L_m"].contains(case["L_m"])
        covered_zeta += result["zeta"].contains(case["zeta"])
        z_L.append((result["L_m"].value - case["L_m"]) / (result["L_m"].half_width / Z_95))
        for key in ("theta0", "offset"):  # each within its own 99.9 % interval
            estimate = result[f"{key}_rad"]
            assert within_999(estimate, case[key]), (key, estimate, case[key])
    # 95 % intervals: at least 8 of 10 must cover (P(fewer) < 1.2 % for true coverage).
    assert covered_L >= 8, covered_L
    assert covered_zeta >= 8, covered_zeta
    # no bias in L: the mean of the errors in standard errors, 1/sqrt(10) wide for an
    # honest interval, inside its 99.9 % interval
    assert abs(np.mean(z_L)) < Z_999 / math.sqrt(trials), z_L


def test_large_amplitude_uses_full_simulation_and_recovers():
    rng = np.random.default_rng(7)
    covered = 0
    for _ in range(3):
        case = _random_case(rng, (0.5, 1.5))
        result = fit_free_decay(_record(case, rng, duration_s=8.0))
        assert result.details["fit_model"] == "full simulation"
        covered += result["L_m"].contains(case["L_m"]) and result["zeta"].contains(case["zeta"])
        assert within_999(result["theta0_rad"], case["theta0"]), (result["theta0_rad"], case)
    assert covered >= 2


def test_correlated_noise_widens_the_intervals_enough():
    # AR(1) noise with correlation 0.9 per sample: the white-noise formula would claim
    # intervals sqrt(19) times too narrow; the sandwich must notice.
    rng = np.random.default_rng(99)
    covered, inflation = 0, []
    for _ in range(8):
        case = _random_case(rng, (0.05, 0.15))
        t, theta = free_decay(case["theta0"], case["zeta"], case["L_m"], duration_s=12.0,
                              fs_hz=400.0)
        shocks = rng.normal(0.0, 1e-3 * math.sqrt(1 - 0.81), t.size)
        noise = np.zeros(t.size)
        for i in range(1, t.size):
            noise[i] = 0.9 * noise[i - 1] + shocks[i]
        result = fit_free_decay(Record(t, theta + noise, "free_decay"))
        covered += result["L_m"].contains(case["L_m"])
        inflation.append(result.quality.variance_inflation)
    assert min(inflation) > 4.0
    assert covered >= 6, covered


def test_offset_bad_samples_and_pre_release_hold_are_handled():
    rng = np.random.default_rng(5)
    case = {"L_m": 0.3, "zeta": 0.015, "theta0": 0.15, "offset": 0.08}
    fs = 400.0
    _t, theta = free_decay(case["theta0"], case["zeta"], case["L_m"], duration_s=10.0, fs_hz=fs)
    held = np.full(int(1.5 * fs), case["theta0"])  # held still for 1.5 s before release
    angle = np.concatenate([held, theta]) + case["offset"]
    angle = angle + rng.normal(0.0, 5e-4, angle.size)
    time = np.arange(angle.size) / fs
    bad = rng.choice(np.arange(held.size + 10, angle.size - 10), size=25, replace=False)
    angle[bad[:15]] = np.nan
    spikes = bad[15:]
    angle[spikes] += rng.choice([-1.0, 1.0], size=spikes.size) * rng.uniform(0.2, 1.0, spikes.size)
    result = fit_free_decay(Record(time, angle, "free_decay"))
    assert result.details["release_trim_s"] == pytest.approx(1.5, abs=0.05)
    assert result.details["nonfinite_samples"] == 15
    assert result.details["spike_samples"] + result.details["outlier_samples"] == 10
    assert result["L_m"].contains(case["L_m"])
    assert result["zeta"].contains(case["zeta"])
    assert within_999(result["offset_rad"], case["offset"]), result["offset_rad"]
    assert any("trimmed" in w for w in result.warnings)


def test_pooling_two_records_narrows_the_interval():
    rng = np.random.default_rng(11)
    case = {"L_m": 0.2, "zeta": 0.02, "theta0": 0.12, "offset": 0.0}
    results = [fit_free_decay(_record(case, rng)) for _ in range(2)]
    pooled = pool_free_decays(results)
    assert pooled["L_m"].contains(case["L_m"])
    assert pooled["zeta"].contains(case["zeta"])
    assert pooled["L_m"].half_width < min(r["L_m"].half_width for r in results)


@pytest.mark.parametrize(
    ("duration_s", "fs_hz", "amplitude", "message"),
    [
        (0.5, 400.0, 0.1, "too short"),  # half a period of the 1.1 s pendulum
        (10.0, 400.0, 0.0, "no oscillation"),  # noise only
        (10.0, 5.0, 0.1, "samples per period"),
    ],
)
def test_unfittable_records_raise_a_clear_error(duration_s, fs_hz, amplitude, message):
    rng = np.random.default_rng(1)
    t, theta = free_decay(amplitude, 0.01, 0.3, duration_s=duration_s, fs_hz=fs_hz)
    measured = theta + rng.normal(0.0, 1e-3, t.size)
    with pytest.raises(IdentificationError, match=message):
        fit_free_decay(Record(t, measured, "free_decay"))


@pytest.mark.parametrize("periods", [1.3, 1.45])
def test_a_record_too_short_is_refused_naming_its_true_period(periods):
    # over a period or so the spectrum's peak is broad: the error once named 0.68 s for 1 s
    rng = np.random.default_rng(3)
    period = 2.0 * math.pi * math.sqrt(0.3 / 9.81)  # the 1.1 s pendulum
    t, theta = free_decay(0.1, 0.01, 0.3, duration_s=periods * period, fs_hz=400.0)
    measured = theta + rng.normal(0.0, 1e-3, t.size)
    with pytest.raises(IdentificationError, match="too short") as refused:
        fit_free_decay(Record(t, measured, "free_decay"))
    named = re.search(r"periods of ([0-9.]+) s", str(refused.value))
    assert named is not None, str(refused.value)
    assert float(named.group(1)) == pytest.approx(period, rel=0.03)


def test_a_record_of_less_than_a_period_says_so_rather_than_guess_one():
    t, theta = free_decay(0.1, 0.01, 0.3, duration_s=0.8, fs_hz=400.0)
    measured = theta + np.random.default_rng(4).normal(0.0, 1e-3, t.size)
    with pytest.raises(IdentificationError, match="less than one period of the swing"):
        fit_free_decay(Record(t, measured, "free_decay"))


def test_record_started_while_the_pendulum_is_still_being_lifted():
    # A hand lifts the pendulum from rest to theta0 over 0.4 s (smooth ramp), then lets go:
    # the motion before the top is not free; the fit must start at that turning point.
    rng = np.random.default_rng(21)
    case = {"L_m": 0.15, "zeta": 0.02, "theta0": -0.9, "offset": 0.0}
    fs = 500.0
    _t, theta = free_decay(case["theta0"], case["zeta"], case["L_m"], duration_s=6.0, fs_hz=fs)
    ramp_t = np.arange(int(0.4 * fs)) / fs
    lift = case["theta0"] * (0.4 + 0.6 * np.sin(0.5 * math.pi * ramp_t / 0.4))
    angle = np.concatenate([lift, theta]) + rng.normal(0.0, 1e-3, lift.size + theta.size)
    time = np.arange(angle.size) / fs
    result = fit_free_decay(Record(time, angle, "free_decay"))
    assert result.details["release_trim_s"] == pytest.approx(0.4, abs=0.03)
    assert result["L_m"].contains(case["L_m"])
    assert result["zeta"].contains(case["zeta"])
