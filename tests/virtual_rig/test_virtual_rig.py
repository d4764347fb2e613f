"""The virtual rig as a sample source: contract, table, tachometer, sensors, causes, operator."""

from __future__ import annotations

import itertools
import math
import threading
import time

import numpy as np
import pytest
from scipy.optimize import curve_fit

from analysis.model import Drive, Model, RigParameters
from drivers.limits import ShakerLimits
from drivers.shaker import ShakerAmplifier
from hardware_sim.amplifier_firmware import AmplifierFirmware
from hardware_sim.sample_source import SampleSource
from hardware_sim.virtual_rig import (
    LaserOutput,
    PotentiometerOutput,
    VirtualRig,
    VirtualRigSettings,
)
from tests.shaker.sim_shaker_backend import SimShakerBackend


def _angle_rad(settings: VirtualRigSettings, counts: np.ndarray) -> np.ndarray:
    zero, per_count = settings.angle_counts_to_rad()
    return (counts - zero) * per_count


def _table_m(settings: VirtualRigSettings, counts: np.ndarray) -> np.ndarray:
    zero, per_count = settings.table_counts_to_m()
    return (counts - zero) * per_count


def _fit_sine(t: np.ndarray, x: np.ndarray) -> tuple[float, float, float]:
    """Amplitude, frequency and phase of x = A sin(2 pi f t + phi) + c (least squares)."""
    spectrum = np.abs(np.fft.rfft(x - x.mean()))
    f0 = np.fft.rfftfreq(x.size, t[1] - t[0])[np.argmax(spectrum)]

    def model(t: np.ndarray, a: float, b: float, f: float, c: float) -> np.ndarray:
        return a * np.sin(2 * np.pi * f * t) + b * np.cos(2 * np.pi * f * t) + c

    (a, b, f, _), _ = curve_fit(model, t, x, p0=[x.std() * 1.4, 0.0, f0, 0.0])
    return math.hypot(a, b), f, math.atan2(b, a)


def test_generate_contract() -> None:
    rig = VirtualRig(VirtualRigSettings(sample_rate_hz=4000.0))
    assert isinstance(rig, SampleSource)
    rig.configure(8000.0)
    assert rig.sample_rate_hz == 8000.0
    block = rig.generate(1000)
    assert set(block) == {"angle", "table", "tach"}
    assert block["angle"].dtype == np.int32 and block["table"].dtype == np.int32
    assert block["tach"].dtype == bool
    assert all(v.shape == (1000,) for v in block.values())
    assert rig.time_s == pytest.approx(1000 / 8000.0)
    rig.generate(0)
    rig.configure(2000.0)  # time goes on where it was
    rig.generate(500)
    assert rig.time_s == pytest.approx(0.125 + 0.25)
    assert rig.state()[0] == pytest.approx(0.375 - 1 / 2000.0)


def test_table_follows_the_shaker_commanded_through_the_driver() -> None:
    settings = VirtualRigSettings(sample_rate_hz=5000.0)
    rig = VirtualRig(settings)
    firmware = AmplifierFirmware(rig.shaker, plant_clock=None)  # the rig's clock moves the shaker
    with ShakerAmplifier(SimShakerBackend(firmware), ShakerLimits()) as shaker:
        shaker.ramp_rate_m_s = 0.01
        shaker.frequency_hz = 7.3
        shaker.amplitude_m = 0.0025
        shaker.enabled = True
        rig.advance(1.5)  # ramp 0.25 s, then settle (tau 50 ms)
        assert not shaker.measured().ramping
        t0 = rig.time_s
        block = rig.generate(10_000)
    t = t0 + np.arange(10_000) / settings.sample_rate_hz
    amplitude, frequency, phase = _fit_sine(t, _table_m(settings, block["table"]))
    assert amplitude == pytest.approx(0.0025, rel=2e-3)
    assert frequency == pytest.approx(7.3, rel=1e-5)
    # one tach pulse per period, on the first sample at or after drive phase 0
    edges = np.flatnonzero(block["tach"])
    period = settings.sample_rate_hz / 7.3
    assert np.all(np.abs(np.diff(edges) - period) <= 1.0)
    assert edges.size in (math.floor(10_000 / period), math.ceil(10_000 / period))
    phase_at_edges = np.mod(2 * np.pi * frequency * t[edges] + phase, 2 * np.pi)
    step = 2 * np.pi * 7.3 / settings.sample_rate_hz
    assert np.all((phase_at_edges >= -1e-3) & (phase_at_edges < step + 1e-3))


def test_laser_clips_outside_its_range() -> None:
    settings = VirtualRigSettings(sample_rate_hz=2000.0, laser=LaserOutput(range_m=0.1))
    rig = VirtualRig(settings)
    rig.shaker.settle_at(amplitude_m=0.07, frequency_hz=2.0)
    x = _table_m(settings, rig.generate(2000)["table"])
    per_count = settings.table_counts_to_m()[1]
    assert x.max() == pytest.approx(0.05, abs=per_count)
    assert x.min() == pytest.approx(-0.05, abs=per_count)
    assert np.mean(np.abs(x) > 0.0499) > 0.3  # flat tops where the table leaves the range


def test_excitation_amplitude_cause_scales_the_true_table_motion() -> None:
    model = Model(drive=Drive(0.002, 5.0)).with_extension("excitation_amplitude", eps=0.1)
    settings = VirtualRigSettings(model=model, sample_rate_hz=2000.0)
    rig = VirtualRig(settings)
    block = rig.generate(4000)
    t = np.arange(4000) / 2000.0
    amplitude, frequency, _ = _fit_sine(t, _table_m(settings, block["table"]))
    assert amplitude == pytest.approx(0.0022, rel=2e-3)  # the laser sees A (1 + eps)
    assert frequency == pytest.approx(5.0, rel=1e-5)
    assert rig.shaker.output().amplitude_m == pytest.approx(0.002)  # the amplifier thinks A


@pytest.mark.parametrize("offset_rad", [0.0, 0.0123, -0.04])
def test_sensor_offset_shows_in_the_angle_channel(offset_rad: float) -> None:
    model = Model()
    if offset_rad:
        model = model.with_extension("sensor_offset", offset_rad=offset_rad)
    settings = VirtualRigSettings(
        model=model, potentiometer=PotentiometerOutput(offset_v=0.5, gain_v_per_rad=4.0)
    )
    angle = _angle_rad(settings, VirtualRig(settings).generate(500)["angle"])
    per_count = settings.angle_counts_to_rad()[1]
    # the pendulum hangs at rest: the channel reads the offset through the known calibration
    assert np.all(np.abs(angle - offset_rad) <= per_count)


def test_free_decay_matches_the_linear_damped_solution() -> None:
    settings = VirtualRigSettings(model=Model(barrier=False), sample_rate_hz=1000.0)
    rig = VirtualRig(settings)
    rig.generate(123)  # release later in the stream: time must be handled, not assumed zero
    theta0 = 0.01
    rig.release(theta0)
    angle = _angle_rad(settings, rig.generate(5000)["angle"])
    t = np.arange(5000) / settings.sample_rate_hz
    rp = settings.model.rig
    w, z = rp.omega_rad_s, rp.zeta
    wd = w * math.sqrt(1 - z * z)
    exact = (
        theta0 * np.exp(-z * w * t) * (np.cos(wd * t) + z / math.sqrt(1 - z * z) * np.sin(wd * t))
    )
    per_count = settings.angle_counts_to_rad()[1]
    assert np.max(np.abs(angle - exact)) < 1.5 * per_count


def test_barrier_stops_the_swing_only_while_it_is_in() -> None:
    settings = VirtualRigSettings(model=Model(barrier=False), sample_rate_hz=4000.0)
    rig = VirtualRig(settings)
    rig.release(-0.1)
    free = _angle_rad(settings, rig.generate(2000)["angle"])  # half a period and more
    assert free.max() > 0.09
    rig.set_barrier(True)
    rig.release(-0.1)
    stopped = _angle_rad(settings, rig.generate(2000)["angle"])
    # oracle: linearised impact (docs/MODEL.md section 4) with the entry speed from energy
    rp = settings.model.rig
    speed = rp.l_m * math.sqrt(2 * rp.omega_rad_s**2 * (1 - math.cos(0.1)))
    m_eff = rp.m_kg * rp.L_m**2 / rp.l_m**2
    delta_max = (5 * m_eff * speed**2 / (4 * rp.K_N_per_m1_5)) ** 0.4
    per_count = settings.angle_counts_to_rad()[1]
    assert 0 < stopped.max() <= math.asin(delta_max / rp.l_m) + per_count
    assert stopped[-1] < 0  # it bounced back


def test_hold_then_release() -> None:
    settings = VirtualRigSettings(model=Model(barrier=False), sample_rate_hz=1000.0)
    rig = VirtualRig(settings)
    rig.hold(0.2)
    held = _angle_rad(settings, rig.generate(300)["angle"])
    per_count = settings.angle_counts_to_rad()[1]
    assert np.all(np.abs(held - 0.2) <= per_count)
    rig.release(0.2)
    swing = _angle_rad(settings, rig.generate(300)["angle"])
    assert abs(swing[0] - 0.2) <= per_count and swing.min() < 0


def test_block_size_does_not_change_the_stream() -> None:
    model = Model(drive=Drive(0.003, 6.0)).with_extension("sensor_lag", tau_s=0.01)
    settings = VirtualRigSettings(
        model=model, sample_rate_hz=3000.0, angle_noise_rad=1e-3, table_noise_m=1e-5, seed=7
    )
    whole = VirtualRig(settings).generate(3000)
    pieces_rig = VirtualRig(settings)
    parts = [pieces_rig.generate(n) for n in (7, 1500, 1, 1492)]
    pieces = {k: np.concatenate([p[k] for p in parts]) for k in whole}
    np.testing.assert_array_equal(pieces["table"], whole["table"])
    np.testing.assert_array_equal(pieces["tach"], whole["tach"])
    # the lag filter and the noise carry over between blocks; the integrator may
    # stop at different times, so allow one count of rounding
    assert np.max(np.abs(pieces["angle"] - whole["angle"])) <= 1


def test_commands_from_another_thread_while_generating() -> None:
    rig = VirtualRig(VirtualRigSettings(sample_rate_hz=20_000.0))
    errors: list[BaseException] = []
    commands = [0]
    done = threading.Event()

    def command() -> None:
        try:
            while not done.is_set():
                i = commands[0] = commands[0] + 1
                rig.shaker.set_targets(amplitude_m=0.001 * (i % 3), frequency_hz=5.0 + i % 4)
                rig.set_barrier(i % 2 == 0)
                time.sleep(0)  # let the generating thread in: locks are not fair
        except BaseException as error:  # reported below
            errors.append(error)

    worker = threading.Thread(target=command)
    worker.start()
    try:
        total = sum(rig.generate(1000)["angle"].size for _ in range(40))
    finally:
        done.set()
        worker.join()
    assert errors == []
    assert commands[0] > 0  # commands really came while it generated
    assert total == 40_000 and rig.samples_generated == 40_000


def test_coulomb_friction_from_configuration_decays_linearly() -> None:
    # oracle: with dry friction only (zeta = 0), each half swing loses 2 Tc / (m L^2 omega^2)
    tc = 2e-4
    rp = RigParameters(zeta=0.0)
    model = Model(rig=rp, barrier=False).with_extension("coulomb_friction", Tc_N_m=tc)
    settings = VirtualRigSettings(model=model, sample_rate_hz=2000.0)
    rig = VirtualRig(settings)
    rig.release(0.15)
    angle = _angle_rad(settings, rig.generate(4000)["angle"])
    crossings = np.flatnonzero(np.diff(np.sign(angle)) != 0)
    extremes = [np.abs(angle[a:b]).max() for a, b in itertools.pairwise(crossings)]
    loss = 2 * tc / (rp.m_kg * rp.L_m**2 * rp.omega_rad_s**2)
    steps = -np.diff([0.15, *extremes])
    assert len(steps) >= 3
    np.testing.assert_allclose(steps, loss, rtol=0.01)


def test_potentiometer_linearity_and_adc_saturation() -> None:
    pot = PotentiometerOutput(offset_v=0.2, gain_v_per_rad=3.0, linearity_v=(0.0, 0.5))
    settings = VirtualRigSettings(potentiometer=pot)
    rig = VirtualRig(settings)
    lsb = settings.adc.lsb_v
    rig.hold(0.3)
    expected = math.floor((0.2 + 3.0 * 0.3 + 0.5 * 0.3**3) / lsb + 0.5)
    assert set(rig.generate(10)["angle"]) == {expected}
    rig.hold(4.0)  # 12.2 V: beyond the +-10 V converter
    assert set(rig.generate(10)["angle"]) == {2**15 - 1}


def test_excitation_distortion_adds_the_second_harmonic() -> None:
    model = Model(drive=Drive(0.002, 4.0)).with_extension(
        "excitation_distortion", h2=0.2, phi2_rad=0.5
    )
    settings = VirtualRigSettings(model=model, sample_rate_hz=2000.0)
    block = VirtualRig(settings).generate(4000)
    t = np.arange(4000) / 2000.0
    x = _table_m(settings, block["table"])
    # linear least squares on the known harmonics: x = A sin(w t) + A h2 sin(2 w t + phi2)
    w = 2 * np.pi * 4.0
    basis = np.column_stack(
        [np.sin(w * t), np.cos(w * t), np.sin(2 * w * t), np.cos(2 * w * t), np.ones_like(t)]
    )
    (s1, c1, s2, c2, _), *_ = np.linalg.lstsq(basis, x, rcond=None)
    assert math.hypot(s1, c1) == pytest.approx(0.002, rel=2e-3)
    assert math.atan2(c1, s1) == pytest.approx(0.0, abs=2e-3)  # phase 0 at t = 0
    assert math.hypot(s2, c2) == pytest.approx(0.0004, rel=1e-2)
    assert math.atan2(c2, s2) == pytest.approx(0.5, abs=1e-2)
