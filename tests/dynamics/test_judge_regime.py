"""The regime of forced records judged from the data, aware of the noise.

Records come from generators that know nothing of the judgement: analytic periodic
and quasi-periodic signals, the project's simulator and its virtual rig (the physics,
the sensor noise and the ADC a demo sweep records through).  The judgement is told
only what a lab knows: the sample rate, the sensor noise, the stated drive and the
tach pulses.  Each case runs over several noise draws.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from analysis.dynamics import judge_record_regime, judge_regime, strobe_record
from analysis.model import Drive, Model, paper_case
from analysis.simulate import SimulationSettings, simulate
from hardware_sim.virtual_rig import VirtualRig, VirtualRigSettings
from rig.config import load_config
from rig.demo.settings import FULL

FS = 1000.0
SEEDS = (11, 12, 13)
GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def _forced_motion(t: np.ndarray, drive_hz: float, rng: np.random.Generator) -> np.ndarray:
    """A period-1 response with a superharmonic, at a random phase to the drive."""
    w = 2 * math.pi * drive_hz
    return 0.08 * np.sin(w * t + rng.uniform(0, 2 * math.pi)) + 0.02 * np.sin(
        2 * w * t + rng.uniform(0, 2 * math.pi)
    )


def _period_k_motion(k: int, t: np.ndarray, drive_hz: float, rng) -> np.ndarray:
    """Period k drive periods: lines at m f / k (m = 1 .. k - 1) of a few mrad each."""
    theta = _forced_motion(t, drive_hz, rng)
    for m in range(1, k):
        amplitude = 6e-3 * rng.uniform(0.5, 1.5)
        theta += amplitude * np.sin(2 * math.pi * m * drive_hz / k * t + rng.uniform(0, 6.3))
    return theta


def _lab_tach(n_samples: int, drive_hz: float, rng) -> np.ndarray:
    """Pulses at drive phase 0 on the first sample at or after it (the tach line is
    sampled) give or take one, one missing, one doubled by a bounce and one spurious."""
    crossings = np.arange(0.0, n_samples - 1.0, FS / drive_hz)
    pulses = np.ceil(crossings) + rng.integers(-1, 2, crossings.size)
    pulses = np.delete(pulses, 17)
    extra = [pulses[30] + 1, pulses[60] + 0.5 * FS / drive_hz]
    pulses = np.sort(np.concatenate([pulses, extra]))
    return pulses[(pulses >= 0) & (pulses < n_samples)]


def _record(theta: np.ndarray, noise_rad: float, rng) -> np.ndarray:
    return theta + noise_rad * rng.normal(size=theta.size)


@pytest.mark.parametrize(
    ("k", "noise_rad", "drive_hz"),
    [
        (1, 2e-3, 10.0),
        (2, 3e-4, 7.3),
        (2, 2e-3, 10.0),
        (3, 1e-3, 7.3),
        (5, 2e-3, 10.0),
        (32, 3e-4, 10.0),
        (32, 2e-3, 7.3),
    ],
)
def test_a_noisy_period_k_orbit_is_judged_period_k(k, noise_rad, drive_hz):
    t = np.arange(int(40 * FS)) / FS
    for seed in SEEDS:
        rng = np.random.default_rng([seed, k])
        theta = _record(_period_k_motion(k, t, drive_hz, rng), noise_rad, rng)
        tach = _lab_tach(t.size, drive_hz, rng)
        regime, strobe = judge_record_regime(
            theta, FS, noise_rad, tach_indices=tach, frequency_hz=drive_hz
        )
        assert (regime.kind, regime.period) == ("periodic", k), regime.label
        assert regime.evidence["transient_periods"] == 0
        assert regime.label.startswith(f"period-{k}")
        assert strobe.clock.missing_pulses == 1 and strobe.clock.extra_pulses == 2


def test_a_slowly_decaying_transient_does_not_hide_the_period():
    """A period-2 orbit with the free oscillation (0.232 f) still dying away: at the end
    of the record it is several times the noise, so no part of it repeats within the noise."""
    drive_hz, noise_rad = 10.0, 3e-4
    t = np.arange(int(40 * FS)) / FS
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        free = 0.03 * np.exp(-t / 10.0) * np.sin(2 * math.pi * 0.232 * drive_hz * t + 1.0)
        theta = _record(_period_k_motion(2, t, drive_hz, rng) + free, noise_rad, rng)
        regime, _ = judge_record_regime(theta, FS, noise_rad, frequency_hz=drive_hz)
        assert (regime.kind, regime.period) == ("periodic", 2), regime.label
        settling = regime.evidence["settling"]
        assert 0.98 < settling["decay_per_period"] < 1.0  # e^(-0.1 / 10 s) per period, and more
        assert settling["difference_second_half_rad"] > 3 * noise_rad
        assert "settling" in regime.label


def test_a_transient_that_dies_early_is_named_and_left_out():
    drive_hz, noise_rad = 10.0, 1e-3
    t = np.arange(int(40 * FS)) / FS
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        # a large swing at first, whose change over 3 periods falls within the tolerance
        # (3 noises of a difference, ~3 mrad) after 4 to 5 s
        free = 0.1 * np.exp(-t / 1.2) * np.sin(2 * math.pi * 0.232 * drive_hz * t)
        theta = _record(_period_k_motion(3, t, drive_hz, rng) + free, noise_rad, rng)
        regime, strobe = judge_record_regime(theta, FS, noise_rad, frequency_hz=drive_hz)
        assert regime.period == 3, regime.label
        transient_s = regime.evidence["transient_s"]
        assert 3.0 < transient_s < 8.0
        assert regime.evidence["settled_periods"] == len(strobe) - regime.evidence[
            "transient_periods"
        ]


def test_quasi_periodic_motion_is_neither_periodic_nor_chaotic():
    drive_hz = 10.0
    t = np.arange(int(60 * FS)) / FS
    w = 2 * math.pi * drive_hz
    for noise_rad in (3e-4, 2e-3):
        for seed in SEEDS:
            rng = np.random.default_rng(seed)
            torus = 0.02 * np.sin(GOLDEN * w * t) + 0.01 * np.sin(2 * GOLDEN * w * t + 0.5)
            theta = _record(_forced_motion(t, drive_hz, rng) + torus, noise_rad, rng)
            regime, _ = judge_record_regime(theta, FS, noise_rad, frequency_hz=drive_hz)
            assert regime.kind == "quasi_periodic", regime.label
            assert regime.evidence["K"] < 0.5
            assert regime.evidence["lyapunov_per_period"] is None


@pytest.fixture(scope="module")
def case_i_run():
    """Paper case i (chaotic) from rest, 10 s of transient skipped, 60 s at 1 kHz."""
    rig, drive = paper_case("i").dimensional()
    run = simulate(
        Model(rig, drive), 0.0, 0.0,
        settings=SimulationSettings(duration_s=60.0, fs_hz=FS, skip_s=10.0, rtol=1e-8, atol=1e-10),
    )
    assert run.ok, run.status
    return run, drive.frequency_hz


@pytest.mark.parametrize("noise_rad", [3e-4, 2e-3])
def test_a_chaotic_record_is_judged_chaotic_by_both_tests(case_i_run, noise_rad):
    run, drive_hz = case_i_run
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        theta = _record(run.theta, noise_rad, rng)
        tach = _lab_tach(theta.size, drive_hz, rng)  # the run starts at drive phase 0
        regime, _ = judge_record_regime(
            theta, FS, noise_rad, tach_indices=tach, frequency_hz=drive_hz
        )
        assert regime.kind == "chaotic", regime.label
        assert regime.evidence["K"] > 0.8
        # the model's own exponent is ~0.3 per period (tangent dynamics)
        assert 0.1 < regime.evidence["lyapunov_per_period"] < 1.0


def _demo_sweep_step(model: Model, seed: int, release_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """The first step of the full demo's sweep on the virtual rig: the shaker ramps from rest
    to the step's drive, the sweep waits its settle time, then records its dwell."""
    config = load_config()
    settings = VirtualRigSettings(
        model=replace(model, drive=Drive()),
        sample_rate_hz=FULL.sample_rate_hz,
        angle_noise_rad=config.virtual.noise_rad,
        seed=seed,
        theta0_rad=release_rad,
    )
    rig = VirtualRig(settings)
    rig.shaker.set_targets(
        amplitude_m=model.drive.amplitude_m, frequency_hz=model.drive.frequency_hz
    )
    rig.advance(FULL.settle_s)
    samples = rig.generate(round(FULL.dwell_s * FULL.sample_rate_hz))
    zero, rad_per_count = settings.angle_counts_to_rad()
    return (samples["angle"] - zero) * rad_per_count, np.flatnonzero(samples["tach"])


@pytest.mark.parametrize(("seed", "release_rad"), [(1, 0.0), (2, -0.01), (3, 0.004)])
def test_paper_case_g_recorded_as_the_demo_records_it_is_period_two(seed, release_rad):
    """beta = 0.022 at 10 Hz: the section shows period 2, reached by a transient that is
    still a few noise levels at the end of the 8 s dwell."""
    rig, drive = paper_case("g").dimensional()
    angle, tach = _demo_sweep_step(Model(rig, drive), seed, release_rad)
    # what the lab knows of its angle channel: the sensor noise and the ADC step
    noise_rad = math.hypot(load_config().virtual.noise_rad, 1e-4 / math.sqrt(12.0))
    regime, strobe = judge_record_regime(
        angle, FULL.sample_rate_hz, noise_rad, tach_indices=tach, frequency_hz=drive.frequency_hz
    )
    assert (regime.kind, regime.period) == ("periodic", 2), regime.label
    assert "1/2 f" in regime.evidence["subharmonics"]
    assert strobe.clock.frequency_hz == pytest.approx(drive.frequency_hz, rel=1e-4)


def test_a_noisy_period_one_orbit_is_never_judged_chaotic():
    """Paper case a (2 Hz, period 1 with impacts) with 2 mrad of noise: period 1; and with
    its noise understated, where the 0-1 test reads the noise as chaos, still not chaotic."""
    rig, drive = paper_case("a").dimensional()
    run = simulate(
        Model(rig, drive), 0.0, 0.0,
        settings=SimulationSettings(duration_s=60.0, fs_hz=FS, skip_s=20.0),
    )
    noise_rad = 2e-3
    for seed in SEEDS:
        rng = np.random.default_rng(seed)
        theta = _record(run.theta, noise_rad, rng)
        strobe = strobe_record(theta, FS, frequency_hz=drive.frequency_hz)
        assert judge_regime(strobe, noise_rad).period == 1
        for understated in (noise_rad / 2, noise_rad / 3):
            regime = judge_regime(strobe, understated)
            assert regime.kind != "chaotic", regime.label
            if regime.kind == "undetermined":
                assert "K = " in regime.label and "divergence" in regime.label


def test_the_evidence_says_what_the_tolerance_and_the_measured_drive_were():
    drive_hz, noise_rad = 10.0, 1e-3
    rng = np.random.default_rng(7)
    t = np.arange(int(20 * FS)) / FS
    theta = _record(_period_k_motion(2, t, drive_hz, rng), noise_rad, rng)
    tach = _lab_tach(t.size, drive_hz, rng)
    regime, strobe = judge_record_regime(
        theta, FS, noise_rad, tach_indices=tach, frequency_hz=10.02
    )
    clock = regime.evidence["clock"]
    assert clock["source"] == "tach"
    assert clock["frequency_hz"] == pytest.approx(drive_hz, rel=1e-4)
    assert clock["stated_frequency_hz"] == 10.02
    # 3 noises of a difference of two points, each the sample noise through its fit and the
    # clock's uncertainty through the angle's slope
    point_noise = np.hypot(noise_rad * strobe.noise_gain, strobe.timing_noise_rad)
    assert regime.evidence["tolerance_rad"] == pytest.approx(
        3 * math.sqrt(2) * np.median(point_noise)
    )
    assert np.median(strobe.timing_noise_rad) < 0.5 * noise_rad * np.median(strobe.noise_gain)
    assert regime.evidence["recurrence"][0] > 10  # lag 1: far outside the noise
    assert regime.evidence["recurrence"][1] < 1.5  # lag 2: within it


def test_bad_input_is_refused_naming_what_was_wrong():
    strobe = strobe_record(np.zeros(int(5 * FS)), FS, frequency_hz=10.0)
    with pytest.raises(ValueError, match="noise"):
        judge_regime(strobe, 0.0)
    short = strobe_record(np.zeros(int(0.5 * FS)), FS, frequency_hz=10.0)
    with pytest.raises(ValueError, match="drive periods"):
        judge_regime(short, 1e-3)
