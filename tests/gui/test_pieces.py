"""The GUI's pure parts: min/max decimation, the sample rings, settings, Poincare accumulation."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.interfaces import PulseBlock, SampleBlock
from gui.decimate import min_max_decimate
from gui.live_data import ChannelRing, LiveData
from gui.settings import AppSettings
from gui.views.poincare_view import PoincareAccumulator


def test_decimation_keeps_every_columns_extremes_in_time_order():
    rng = np.random.default_rng(3)
    y = rng.normal(size=100_003)
    y[51_234] = 40.0  # a single-sample spike must survive
    x = np.arange(y.size) / 1000.0
    xd, yd = min_max_decimate(x, y, 500)
    assert xd.size <= 2 * 500
    assert np.all(np.diff(xd) >= 0)
    per_bin = -(-y.size // 500)
    starts = np.arange(0, y.size, per_bin)
    # oracle: brute-force extremes of each bin, compared with the pairs returned
    low = [y[s : s + per_bin].min() for s in starts]
    high = [y[s : s + per_bin].max() for s in starts]
    assert np.array_equal(np.minimum(yd[0::2], yd[1::2]), low)
    assert np.array_equal(np.maximum(yd[0::2], yd[1::2]), high)
    assert xd[-1] >= x[-per_bin]  # the drawing reaches the newest samples
    assert 40.0 in yd
    assert yd.max() == y.max() and yd.min() == y.min()


def test_short_traces_are_drawn_unchanged():
    x = np.arange(10.0)
    xd, yd = min_max_decimate(x, x**2, 100)
    assert np.array_equal(xd, x) and np.array_equal(yd, x**2)
    with pytest.raises(ValueError, match="equal length"):
        min_max_decimate(x, x[:5], 10)


def test_ring_keeps_the_newest_samples_across_the_wrap():
    ring = ChannelRing(1000)
    everything = np.arange(3500, dtype=float) * 0.5
    for start in range(0, 3500, 333):
        ring.append(10_000 + start, everything[start : start + 333])
    indices, values = ring.latest()
    assert ring.count == 1000 and ring.end_index == 13_500
    assert np.array_equal(indices, np.arange(12_500, 13_500))
    assert np.array_equal(values, everything[2500:])
    indices, values = ring.since(13_400)
    assert np.array_equal(indices, np.arange(13_400, 13_500))


def test_live_data_takes_blocks_and_measures_the_drive_from_the_tach():
    fs = 1000.0
    data = LiveData(fs, keep_s=5.0)
    values = np.sin(np.arange(2000) / fs * 2 * np.pi * 4.0)
    data.ingest(
        [
            SampleBlock("angle", 0, 0.0, fs, values.astype(np.int16), values),
            PulseBlock("tach", 0, 2000, np.arange(0, 2000, 250), np.arange(0, 2, 0.25)),
        ]
    )
    assert data.angle.end_index == 2000
    assert data.drive_frequency_hz() == pytest.approx(4.0)


def test_poincare_of_a_period_one_signal_is_one_point():
    """Sampling sin(2 pi f t) once per period at phase 0 gives theta = 0, theta' = 2 pi f A."""
    fs, f, amplitude = 2000.0, 5.0, 0.2
    data = LiveData(fs, keep_s=10.0)
    n = int(4 * fs)
    t = np.arange(n) / fs
    theta = amplitude * np.sin(2 * np.pi * f * t)
    edges = np.arange(0, n, int(fs / f))
    data.ingest(
        [
            SampleBlock("angle", 0, 0.0, fs, theta.astype(np.int16), theta),
            PulseBlock("tach", 0, n, edges, edges / fs),
        ]
    )
    acc = PoincareAccumulator()
    added = acc.update(data)
    assert added >= len(edges) - 2  # the last pulse waits for the samples after it
    assert np.allclose(acc.theta, 0.0, atol=1e-6)
    assert np.allclose(acc.theta_dot, 2 * np.pi * f * amplitude, rtol=1e-3)
    data.clear()
    acc.update(data)
    assert acc.theta.size == 0  # a new source starts a new section


def test_settings_go_to_the_given_file(tmp_path):
    path = tmp_path / "s.ini"
    first = AppSettings(str(path))
    first.set("shaker/frequency_hz", 12.5)
    first.set("views/spectrum_log", False)
    first.sync()
    again = AppSettings(str(path))
    assert again.number("shaker/frequency_hz", 0.0) == 12.5
    assert again.flag("views/spectrum_log", True) is False
    assert again.location == str(path)


def test_the_tach_frequency_is_measured_over_the_newest_run_of_like_pulses():
    """Whole-sample marks of a 9.987 Hz drive at 2 kHz (an edge is up to a sample late,
    so two periods alone err by ~0.25 %), one pulse missed, then a step to 10.4 Hz: the
    frequency comes from the pulses after the step, within a sample over their span."""
    fs = 2000.0
    data = LiveData(fs, keep_s=20.0)
    rng = np.random.default_rng(4)
    first = np.arange(0.0, 6.0, 1 / 9.987) + rng.uniform(0, 1 / 9.987)
    first = np.delete(first, 40)
    second = first[-1] + np.arange(1, 12) / 10.4
    edges = np.ceil(np.concatenate([first, second]) * fs).astype(np.int64)
    n = int(edges[-1]) + 50
    data.ingest([
        SampleBlock("angle", 0, 0.0, fs, np.zeros(n, np.int16), np.zeros(n)),
        PulseBlock("tach", 0, n, edges, edges / fs),
    ])
    span_periods = 11
    assert data.drive_frequency_hz() == pytest.approx(10.4, rel=1.0 / (span_periods * fs / 10.4))
    # before the step, the missed pulse is outside the newest run
    early = LiveData(fs, keep_s=20.0)
    stop = int(edges[len(first) - 1]) + 50
    early.ingest([
        SampleBlock("angle", 0, 0.0, fs, np.zeros(stop, np.int16), np.zeros(stop)),
        PulseBlock("tach", 0, stop, edges[: len(first)], edges[: len(first)] / fs),
    ])
    assert early.drive_frequency_hz() == pytest.approx(9.987, rel=1.0 / (16 * fs / 9.987))
