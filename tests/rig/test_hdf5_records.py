"""Analysis reads recordings as ``Record`` objects: uniform segments only, never filled gaps."""

from __future__ import annotations

import time

import numpy as np
import pytest

from analysis.hdf5_records import load_hdf5_segments
from analysis.record_loaders import load_record
from recording.errors import RecordFormatError
from tests.rig.test_replay import _make_recording


def test_a_clean_recording_loads_as_one_record_with_its_tach_and_metadata(tmp_path):
    from rig.engine import AcquisitionEngine
    from rig.recorder import Recorder, attach_recorder
    from tests.rig.streams import CounterStream, TachStream
    from tests.rig.test_recorder import META, SPECS

    path = tmp_path / "clean.h5"
    streams = [
        CounterStream("angle", total=5000),
        CounterStream("table", total=5000, gain=2e-3),
        TachStream(total=5000, period=1000),
    ]
    engine = AcquisitionEngine(streams)
    recorder = Recorder(path, SPECS, META)
    thread = attach_recorder(engine, recorder)
    engine.start()
    while min(s.next_index for s in streams) < 5000:
        time.sleep(0.01)
    engine.stop()
    thread.join(10)
    recorder.close()
    record = load_record(path)
    index = np.arange(5000)
    np.testing.assert_allclose(record.angle_rad, index * 1e-3, rtol=1e-7)
    np.testing.assert_allclose(record.table_m, index * 2e-3, rtol=1e-7)
    np.testing.assert_allclose(record.time_s, index / 10_000.0)
    np.testing.assert_array_equal(record.tach_indices, [0, 1000, 2000, 3000, 4000])
    assert record.experiment == "forced"
    assert record.drive["frequency_hz"] == 10.0
    assert record.rig["m_kg"] == 0.0326 and record.rig["R_m"] is None


def test_a_recording_with_gaps_is_refused_whole_and_split_into_uniform_segments(tmp_path):
    path = _make_recording(tmp_path / "gappy.h5")  # angle loses 7000+321, 25000+5; table 12345+1000
    with pytest.raises(RecordFormatError, match="gap"):
        load_record(path)
    segments = load_hdf5_segments(path)
    starts = [round(float(s.time_s[0]) * 10_000) for s in segments]
    assert starts == [0, 7_321, 13_345, 25_005]
    for segment, start in zip(segments, starts, strict=True):
        index = start + np.arange(segment.time_s.size)
        np.testing.assert_allclose(segment.angle_rad, index * 1e-3, rtol=1e-7)
        np.testing.assert_allclose(segment.table_m, index * 2e-3, rtol=1e-7)
        assert np.all(np.diff(segment.time_s) == pytest.approx(1e-4))
