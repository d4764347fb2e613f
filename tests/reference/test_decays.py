"""The decay generator: the same seed gives the same files, the files tell nothing of the
truth, and each cause and effect drawn does to the record what it says."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy import stats

from reference.decays import (
    ADC_STEP_RAD,
    EFFECTS,
    FREE,
    IMPACT,
    LIBRARY_TERMS,
    PAIRS,
    draw_decay,
)

SHORT_S = 6.0  # decays are cut to this for speed


def _twins(seed: int, effect: str, duration_s: float = SHORT_S):
    """A decay with the effect and its neutral twin (same numbers, no effect)."""
    experiment = EFFECTS[effect].experiment
    return (draw_decay(seed, experiment, effect=effect, duration_s=duration_s),
            draw_decay(seed, experiment, effect=effect, neutral=True, duration_s=duration_s))


def test_the_same_seed_writes_the_same_bytes(tmp_path):
    pair = PAIRS[0]
    paths = [draw_decay(5, pair.experiment, pair.causes, duration_s=SHORT_S).write(
        tmp_path / name, "decay") for name in ("a", "b") if not (tmp_path / name).mkdir()]
    for suffix in (".csv", ".json"):
        first, second = (p.with_suffix(suffix).read_bytes() for p in paths)
        assert first == second
    other = draw_decay(6, pair.experiment, pair.causes, duration_s=SHORT_S).write(tmp_path,
                                                                                 "other")
    assert other.read_bytes() != paths[0].read_bytes()


@pytest.mark.parametrize(("experiment", "causes", "effect"), [
    (FREE, ("coulomb_friction", "sensor_offset"), None),
    (IMPACT, ("barrier_offset", "sensor_lag"), None),
    (FREE, (), "cubic_rate_damping"),
    (IMPACT, (), "compliant_barrier_mount"),
])
def test_the_files_state_only_what_a_lab_knows(tmp_path, experiment, causes, effect):
    decay = draw_decay(11, experiment, causes, effect, duration_s=3.0)
    path = decay.write(tmp_path, "decay")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["decay.csv", "decay.json"]
    meta = json.loads(path.with_suffix(".json").read_text())
    assert meta == {"format_version": meta["format_version"], "experiment": experiment,
                    "rig": {"m_kg": 0.0326, "l_m": 0.05, "R_m": 0.0095, "g": 9.81},
                    "notes": ""}
    text = path.read_text()
    assert text.splitlines()[0] == "time_s,angle_rad"
    words = set(causes) | ({effect} if effect else set())
    for values in [*decay.causes.values(), decay.effect_values]:
        words |= set(values)
    for word in words:
        assert word not in text and word not in path.with_suffix(".json").read_text()


def test_sensor_causes_compose_as_the_model_says():
    # measured = theta + k3 theta^3 + offset (no lag): exactly, up to the converter's step
    causes = ("sensor_nonlinearity", "sensor_offset")
    decay = draw_decay(21, FREE, causes, duration_s=SHORT_S)
    clean = draw_decay(21, FREE, causes, neutral=True, duration_s=SHORT_S)
    k3 = decay.causes["sensor_nonlinearity"]["k3"]
    offset = decay.causes["sensor_offset"]["offset_rad"]
    expected = k3 * decay.theta_rad**3 + offset
    np.testing.assert_array_equal(decay.theta_rad, clean.theta_rad)
    assert np.max(np.abs(decay.angle_rad - clean.angle_rad - expected)) <= 1.01 * ADC_STEP_RAD


def test_a_lagged_sensor_trails_the_angle_by_its_time_constant():
    decay = draw_decay(22, IMPACT, ("sensor_lag", "barrier_offset"), duration_s=3.0)
    clean = draw_decay(22, IMPACT, ("sensor_lag", "barrier_offset"), neutral=True,
                       duration_s=3.0)
    tau = decay.causes["sensor_lag"]["tau_s"]
    # the truth moves (the barrier offset acts); the reading, not the angle, is lagged:
    # a first-order filter of theta sampled at the reading's times
    t, theta = decay.t_s, decay.theta_rad
    dt = t[1] - t[0]
    lagged = np.empty_like(theta)
    lagged[0] = theta[0]
    for i in range(1, t.size):  # exact for an angle linear between samples
        a = math.exp(-dt / tau)
        slope = (theta[i] - theta[i - 1]) / dt
        lagged[i] = theta[i] - tau * slope + a * (lagged[i - 1] - theta[i - 1] + tau * slope)
    noise = decay.angle_rad - lagged
    assert np.std(noise) == pytest.approx(decay.noise_rad, rel=0.1)
    assert not np.array_equal(theta, clean.theta_rad)


def test_hum_adds_exactly_its_line():
    hum, clean = _twins(31, "mains_hum")
    v = hum.effect_values
    expected = v["amplitude_rad"] * np.sin(2 * np.pi * v["frequency_hz"] * hum.t_s
                                           + v["phase_rad"])
    assert np.max(np.abs(hum.angle_rad - clean.angle_rad - expected)) <= 1.01 * ADC_STEP_RAD


def test_drifts_add_exactly_their_trend():
    drift, clean = _twins(32, "sensor_zero_drift")
    along = (drift.t_s - drift.t_s[0]) / (drift.t_s[-1] - drift.t_s[0])
    change = drift.angle_rad - clean.angle_rad
    assert np.max(np.abs(change - drift.effect_values["offset_change_rad"] * along)) \
        <= 1.01 * ADC_STEP_RAD
    gain, clean = _twins(33, "sensor_gain_drift")
    along = (gain.t_s - gain.t_s[0]) / (gain.t_s[-1] - gain.t_s[0])
    change = gain.angle_rad - clean.angle_rad
    assert np.max(np.abs(change - gain.effect_values["gain_change"] * along * gain.theta_rad)) \
        <= 1.01 * ADC_STEP_RAD


def test_backlash_trails_the_motion_by_half_the_play():
    play, clean = _twins(34, "sensor_backlash")
    change = play.angle_rad - clean.angle_rad
    half = play.effect_values["play_rad"] / 2
    assert np.max(np.abs(change)) <= half + 1.01 * ADC_STEP_RAD
    # while the pendulum swings the play is taken up: the reading trails by half of it,
    # against the motion
    rate = np.gradient(play.theta_rad, play.t_s)
    fast = np.abs(rate) > 0.2
    assert np.median(-np.sign(rate[fast]) * change[fast]) == pytest.approx(half, rel=0.05)


def test_spikes_are_rare_and_large():
    spiky, clean = _twins(41, "noise_spikes")
    change = np.abs(spiky.angle_rad - clean.angle_rad)
    hits = np.count_nonzero(change > 7.9 * spiky.noise_rad)
    assert hits == pytest.approx(spiky.effect_values["fraction"] * spiky.t_s.size, rel=0.25)
    assert np.count_nonzero(change > ADC_STEP_RAD) == hits


@pytest.mark.parametrize(("seed", "effect"), [(42, "noise_decoy_free"),
                                              (43, "noise_decoy_impact"), (44, None)])
def test_the_decoys_noise_is_white_and_only_slightly_heavy_tailed(seed, effect):
    experiment = EFFECTS[effect].experiment if effect else FREE
    decoy = draw_decay(seed, experiment, effect=effect, duration_s=20.0 if effect is None
                       or experiment == FREE else SHORT_S)
    noise = decoy.angle_rad - decoy.theta_rad
    assert np.std(noise) == pytest.approx(decoy.noise_rad, rel=0.1)
    assert abs(np.corrcoef(noise[1:], noise[:-1])[0, 1]) < 0.05  # white
    if effect is None:
        assert abs(stats.kurtosis(noise)) < 0.2  # Gaussian
    else:
        assert 0.5 < stats.kurtosis(noise) < 10.0  # Student's t, 4-8 degrees of freedom


def _crossings(theta: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Times where theta crosses 0 upward (linear interpolation)."""
    i = np.flatnonzero((theta[:-1] < 0) & (theta[1:] >= 0))
    return t[i] - theta[i] * (t[i + 1] - t[i]) / (theta[i + 1] - theta[i])


def _peaks(theta: np.ndarray) -> np.ndarray:
    inner = (np.abs(theta[1:-1]) > np.abs(theta[:-2])) & (np.abs(theta[1:-1])
                                                         >= np.abs(theta[2:]))
    return np.abs(theta[1:-1][inner])


def test_a_stiffening_hairspring_quickens_the_large_swings():
    spring, clean = _twins(51, "pivot_hairspring_stiffening", duration_s=6.0)
    period = np.diff(_crossings(spring.theta_rad, spring.t_s))[:3]
    period_clean = np.diff(_crossings(clean.theta_rad, clean.t_s))[:3]
    assert np.all(period < 0.99 * period_clean)


def test_a_softening_hairspring_slows_the_impacts():
    spring, clean = _twins(52, "pivot_hairspring_softening")
    # the barrier is at 0: each flight between impacts is longer with a softer pivot
    entries = _crossings(spring.theta_rad, spring.t_s)[:5]
    entries_clean = _crossings(clean.theta_rad, clean.t_s)[:5]
    assert np.all(np.diff(entries) > 1.01 * np.diff(entries_clean))


@pytest.mark.parametrize("effect", ["cubic_rate_damping", "angle_rate_damping"])
def test_cubic_dampings_take_more_of_the_large_swings(effect):
    damped, clean = _twins(53, effect, duration_s=10.0)
    ratio = _peaks(damped.theta_rad) / _peaks(clean.theta_rad)[: _peaks(damped.theta_rad).size]
    # the extra loss is fast while the swing is large and slows as it shrinks (a^3 law)
    early = 1.0 - ratio[4] / ratio[0]
    late = 1.0 - ratio[-1] / ratio[-5]
    assert early > 0.005 and late < 0.6 * early


def test_a_compliant_mount_lets_the_pendulum_in_deeper():
    mounted, clean = _twins(54, "compliant_barrier_mount", duration_s=2.0)
    assert np.max(mounted.theta_rad) > 1.15 * np.max(clean.theta_rad)
    assert np.count_nonzero(mounted.theta_rad > 0) > np.count_nonzero(clean.theta_rad > 0)


@pytest.mark.parametrize(("effect", "sign"), [("contact_damping_on_delta", 1.0),
                                              ("contact_damping_on_delta2", -1.0)])
def test_damping_on_another_power_changes_the_late_impacts_loss(effect, sign):
    # equally lossy at the first impact's depth; at the shallower late impacts delta^1
    # damps more than delta^1.5 and delta^2 less: the late swings are smaller or larger
    other, clean = _twins(55, effect, duration_s=8.0)
    late = other.t_s > 0.6 * other.t_s[-1]
    swing = np.ptp(other.theta_rad[late])
    swing_clean = np.ptp(clean.theta_rad[late])
    assert sign * (swing_clean - swing) > 0.05 * swing_clean


def test_the_benchmark_tables_hold_what_the_brief_asks():
    assert len(PAIRS) >= 10 and len({(p.experiment, p.causes) for p in PAIRS}) == len(PAIRS)
    assert {p.experiment for p in PAIRS} == {FREE, IMPACT}
    outside = [e for e, spec in EFFECTS.items() if spec.domain != "noise"]
    assert len(outside) >= 8
    for spec in EFFECTS.values():
        assert (spec.term is not None) == (spec.domain == "physics")


def test_the_library_named_here_is_the_term_proposals():
    # a true term counts as proposable only if today's library on a decay (no drive) holds it
    from analysis.discrepancy.term_proposal import contact_library, flight_library
    from analysis.packed import P

    packed = np.zeros(int(P.SIZE))
    packed[P.BARRIER] = 1.0
    packed[P.SHAFT_L] = 0.05
    x = np.linspace(-0.1, 0.1, 5)
    names = set(flight_library(x, x, x, packed).names) | set(contact_library(x, x, packed).names)
    assert names == LIBRARY_TERMS
    assert {e: s.term_in_library for e, s in EFFECTS.items() if s.term} == {
        "pivot_hairspring_stiffening": True, "pivot_hairspring_softening": True,
        "cubic_rate_damping": True, "angle_rate_damping": True,
        "compliant_barrier_mount": True, "contact_damping_on_delta": True,
        "contact_damping_on_delta2": True}
