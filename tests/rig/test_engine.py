"""The acquisition engine: fan-out without blocking, per-subscriber losses, gaps."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.interfaces import PulseBlock, SampleBlock
from rig.engine import RATE_WINDOW_S, AcquisitionEngine, SubscriberOverrunError, _RateWindow
from rig.events import Gap
from tests.rig.streams import CounterStream, TachStream


def _drain(subscription, until_closed=True):
    out = []
    while True:
        batch = subscription.get_many(timeout_s=0.05)
        out.extend(batch)
        if not batch and subscription.closed:
            return out


def _wait_until(predicate, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return False


def _taken_in(engine, **end_index):
    """Whether the engine has taken in each named channel up to its end index."""
    channels = engine.stats().channels
    return all(channels[name].end_index == end for name, end in end_index.items())


def test_every_sample_reaches_a_keeping_subscriber_and_gaps_are_reported_before_the_block():
    reported = CounterStream("angle", total=20_000, gaps={5_000: 700}, block=333)
    silent = CounterStream("table", total=20_000, gaps={12_000: 55}, report_gaps=False, gain=2e-3)
    engine = AcquisitionEngine([reported, silent])
    keeper = engine.subscribe("recorder", privileged=True)
    engine.start()
    # the engine's own state, not a delay: each stream's last block taken in (stop then
    # lets every reader finish the block it holds)
    assert _wait_until(lambda: _taken_in(engine, angle=20_000, table=20_000))
    engine.stop()
    deliveries = [event for _, event in _drain(keeper)]
    for channel, gap_at, gap_len in (("angle", 5_000, 700), ("table", 12_000, 55)):
        events = [e for e in deliveries if getattr(e, "channel", None) == channel]
        blocks = [e for e in events if isinstance(e, SampleBlock)]
        indices = np.concatenate([np.arange(b.first_index, b.end_index) for b in blocks])
        expected = np.setdiff1d(np.arange(20_000), np.arange(gap_at, gap_at + gap_len))
        np.testing.assert_array_equal(indices, expected)
        np.testing.assert_array_equal(np.concatenate([b.raw for b in blocks]), expected)
        gaps = [e for e in events if isinstance(e, Gap)]
        assert gaps == [Gap(channel, gap_at, gap_len)]
        # the gap comes just before the block that follows it
        position = events.index(gaps[0])
        assert events[position + 1].first_index == gap_at + gap_len
    stats = engine.stats()
    assert stats.channels["angle"].samples_lost == 700
    assert stats.channels["table"].samples_lost == 55
    assert stats.channels["angle"].gaps == 1


def test_a_slow_viewer_loses_only_its_own_view_and_the_loss_is_counted():
    stream = CounterStream("angle", total=50_000, block=100)
    engine = AcquisitionEngine([stream])
    keeper = engine.subscribe("recorder", privileged=True)
    viewer = engine.subscribe("gui", max_items=10)  # never read while acquiring
    engine.start()
    assert _wait_until(lambda: _taken_in(engine, angle=50_000))
    engine.stop()
    kept = [e for _, e in _drain(keeper) if isinstance(e, SampleBlock)]
    seen = [e for _, e in _drain(viewer) if isinstance(e, SampleBlock)]
    assert sum(len(b) for b in kept) == 50_000
    assert len(seen) == 10
    # the viewer keeps the newest blocks
    assert seen[-1].end_index == 50_000
    stats = {s.name: s for s in engine.stats().subscribers}
    assert stats["gui"].dropped_items == 490
    assert stats["gui"].dropped_samples == 49_000
    assert stats["recorder"].dropped_items == 0


def test_a_privileged_subscriber_that_falls_behind_stops_acquisition_loudly():
    stream = CounterStream("angle", block=1000)
    engine = AcquisitionEngine([stream])
    failures = []
    engine.on_failure(failures.append)
    recorder = engine.subscribe("recorder", privileged=True, max_backlog_samples=20_000)
    engine.start()
    assert _wait_until(lambda: engine.error is not None)
    engine.stop()
    assert isinstance(engine.error, SubscriberOverrunError)
    # what was refused past the limit is counted, and the queue keeps an unbroken prefix
    queued = [event for _, event in recorder.get_many(0.0) if isinstance(event, SampleBlock)]
    assert [b.first_index for b in queued] == [1000 * k for k in range(len(queued))]
    assert recorder.dropped_samples >= 1000
    assert recorder.dropped_samples == stream.next_index - 1000 * len(queued)
    assert "recorder" in str(engine.error)
    assert failures == [engine.error]
    with pytest.raises(SubscriberOverrunError):
        engine.raise_if_failed()


def test_the_rate_estimate_is_the_index_advance_over_the_host_time_of_the_last_seconds():
    # host arrival times given, not measured: the estimator itself, deterministically
    window = _RateWindow()
    assert window.add(0.0, 100) == 0.0  # one arrival: no rate yet
    assert window.add(0.1, 600) == 0.0  # under 0.2 s of arrivals: none either
    assert window.add(1.0, 5_100) == pytest.approx(5_000.0)
    # the stream slows to 4 kHz: once the window holds only the last 2 s of arrivals the
    # estimate is the new rate, whatever came before
    for k in range(1, 11):
        rate = window.add(1.0 + 0.5 * k, 5_100 + 2_000 * k)
    assert rate == pytest.approx(4_000.0)
    assert window.arrivals[0][0] >= 6.0 - RATE_WINDOW_S


def test_live_quantities_rate_tach_and_drive():
    stream = CounterStream("angle", sample_rate_hz=5_000, block=100, realtime=True)
    tach = TachStream(sample_rate_hz=5_000, block=100, period=500)
    engine = AcquisitionEngine([stream, tach])
    engine.start()
    # wait on the state the live quantities need (a rate window, two tach edges), not a delay;
    # how close the estimate comes to the board's rate under load is a benchmark figure
    # (benchmarks/bench_record.py), not a test
    assert _wait_until(
        lambda: (lambda c: c["angle"].sample_rate_hz > 0 and c["tach"].edges >= 2)(
            engine.stats().channels
        )
    )
    setting = engine.note_drive(10.0, 0.002, True)
    stats = engine.stats()
    engine.stop()
    assert stats.channels["angle"].sample_rate_hz > 0
    # the tach frequency comes from device time (edge indices / sample rate): exact
    assert stats.channels["tach"].tach_frequency_hz == pytest.approx(10.0)
    assert stats.drive == setting
    assert setting.sample_index > 0


def test_pulse_blocks_are_fanned_out_with_their_edges():
    tach = TachStream(total=5_000, period=1_000, block=300)
    engine = AcquisitionEngine([tach])
    sub = engine.subscribe("analysis", max_items=1000)
    engine.start()
    assert _wait_until(lambda: _taken_in(engine, tach=5_000))
    engine.stop()
    pulses = [e for _, e in _drain(sub) if isinstance(e, PulseBlock)]
    edges = np.concatenate([p.edge_indices for p in pulses])
    np.testing.assert_array_equal(edges, [0, 1000, 2000, 3000, 4000])
