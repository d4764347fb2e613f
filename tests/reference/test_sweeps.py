"""The sweep generator: deterministic, continued from step to step as a rig runs it, and
written as a recording the project's loaders read back step by step."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.hdf5_records import load_hdf5_steps
from analysis.sweep.steps import DOWN, UP
from reference.sweeps import (
    GeneratedSweep,
    draw_sweep,
    sweep_visibility,
    write_sweep_recording,
)

TINY = {"up_steps": 2, "settle_s": 0.5, "dwell_s": 1.5, "sample_rate_hz": 500.0}


@pytest.fixture(scope="module")
def offset_sweep() -> GeneratedSweep:
    return draw_sweep(7, "sensor_offset", parameter="frequency", laser=True, **TINY)


def _bytes(generated: GeneratedSweep) -> bytes:
    parts = []
    for step in generated.sweep.steps:
        record = step.record
        parts += [record.time_s.tobytes(), record.angle_rad.tobytes(),
                  record.tach_indices.tobytes(),
                  b"" if record.table_m is None else record.table_m.tobytes()]
    return b"".join(parts)


def test_same_seed_gives_the_same_bytes(offset_sweep):
    again = draw_sweep(7, "sensor_offset", parameter="frequency", laser=True, **TINY)
    assert _bytes(again) == _bytes(offset_sweep)
    assert again.truth == offset_sweep.truth
    other = draw_sweep(8, "sensor_offset", parameter="frequency", laser=True, **TINY)
    assert _bytes(other) != _bytes(offset_sweep)


def test_steps_run_up_and_back_down_with_their_settle(offset_sweep):
    sweep, truth = offset_sweep.sweep, offset_sweep.truth
    assert sweep.parameter == "frequency"
    assert [s.direction for s in sweep.steps] == [UP, UP, DOWN]
    settings = [sweep.setting(s) for s in sweep.steps]
    assert settings == [4.0, 7.0, 4.0]
    assert len({s.amplitude_m for s in sweep.steps}) == 1
    fs = TINY["sample_rate_hz"]
    for number, step in enumerate(sweep.steps):
        assert step.settle_s == TINY["settle_s"]
        # the dwell begins after this step's settle, right after the previous dwell
        begins = number * (TINY["settle_s"] + TINY["dwell_s"]) + TINY["settle_s"]
        assert step.record.time_s[0] == pytest.approx(begins)
        assert step.record.time_s.size == round(TINY["dwell_s"] * fs)
        assert step.record.drive == {"frequency_hz": step.frequency_hz,
                                     "amplitude_m": step.amplitude_m}
        assert set(step.record.rig) == {"m_kg", "l_m", "R_m", "g"}
    assert truth.causes["sensor_offset"]["offset_rad"] != 0.0
    assert not truth.moves_diagram


def test_state_carries_over_from_step_to_step(offset_sweep):
    """The noiseless angle is continuous across every change of setting (a fresh start
    at each step would jump), and the table's phase runs on."""
    run = offset_sweep.run
    for end in run.dwell_end[:-1]:
        jump = abs(run.true_angle_rad[end] - run.true_angle_rad[end - 1])
        typical = np.median(np.abs(np.diff(run.true_angle_rad)))
        assert jump < 20 * typical
        table_jump = abs(run.table_m[end] - run.table_m[end - 1])
        assert table_jump < 2e-3  # a phase reset would jump by up to twice the amplitude


def test_tach_marks_each_steps_drive_phase(offset_sweep):
    truth = offset_sweep.truth
    for step, drive in zip(offset_sweep.sweep.steps, truth.drives, strict=True):
        pulses = step.record.time_s[step.record.tach_indices]
        spacing = np.diff(pulses)
        assert np.all(np.abs(spacing - 1.0 / drive.frequency_hz) <= 1.0 / truth.sample_rate_hz)
        assert abs(drive.frequency_hz / drive.stated_frequency_hz - 1.0) <= 5e-4


def test_noise_is_what_the_truth_says(offset_sweep):
    run, chain = offset_sweep.run, offset_sweep.truth.measurement
    offset = offset_sweep.truth.causes["sensor_offset"]["offset_rad"]
    error = run.angle_rad - run.true_angle_rad - offset
    assert np.std(error) == pytest.approx(chain.angle_noise_rad, rel=0.05)
    assert chain.angle_noise_rad <= 2e-3
    assert abs(np.mean(error)) < 5 * chain.angle_noise_rad / math.sqrt(error.size)


def test_recording_reads_back_step_by_step(tmp_path, offset_sweep):
    path = write_sweep_recording(offset_sweep, tmp_path / "sweep.h5")
    records = load_hdf5_steps(path)
    assert len(records) == len(offset_sweep.sweep.steps)
    for record, step in zip(records, offset_sweep.sweep.steps, strict=True):
        assert record.drive == step.record.drive
        np.testing.assert_array_equal(record.tach_indices, step.record.tach_indices)
        np.testing.assert_allclose(record.angle_rad, step.record.angle_rad, atol=1e-6)
        np.testing.assert_allclose(record.time_s, step.record.time_s, atol=1e-9)
    with pytest.raises(Exception, match="exists"):
        write_sweep_recording(offset_sweep, path)


def test_bad_requests_are_named():
    with pytest.raises(ValueError, match="cause"):
        draw_sweep(1, "gremlins")
    with pytest.raises(ValueError, match="parameter"):
        draw_sweep(1, parameter="phase")
    with pytest.raises(ValueError, match="up_steps"):
        draw_sweep(1, up_steps=1)


def test_how_much_of_the_cause_shows_over_the_sweep(offset_sweep):
    # a zero offset is the reading minus the true angle on every sample: what the baseline
    # run from the true states misses is the offset itself, and no refit of the rig's
    # omega, zeta, K and mu0, shared by the steps, absorbs a constant
    truth, run = offset_sweep.truth, offset_sweep.run
    offset = truth.causes["sensor_offset"]["offset_rad"]
    assert np.allclose(run.true_reading_rad - run.true_angle_rad, offset)
    seen = sweep_visibility(truth, run, windows_each=1)
    noise = truth.measurement.angle_noise_rad
    assert seen.windows == len(truth.drives)
    assert seen.effect_over_noise == pytest.approx(abs(offset) / noise, rel=1e-3)
    assert seen.shows and seen.visible_over_noise <= seen.effect_over_noise + 1e-9
