"""The CSV + JSON exchange format: round trip, and clear errors on bad files."""

import json
import warnings

import numpy as np
import pytest

from analysis.exchange import (
    ExchangeFormatError,
    ExchangeMeta,
    ExchangeRecord,
    read_exchange,
    write_exchange,
)


def make_record(n=500, fs=1000.0):
    t = np.arange(n) / fs
    tach = np.zeros(n)
    tach[::100] = 1
    meta = ExchangeMeta(
        "forced", {"m_kg": 0.0326, "l_m": 0.05, "R_m": 0.0095, "g": 9.81},
        {"frequency_hz": 10.0, "amplitude_m": 0.005}, "test record",
    )
    return ExchangeRecord(t, 0.1 * np.sin(20 * np.pi * t), meta, 0.005 * np.sin(20 * np.pi * t),
                          tach)


def test_round_trip(tmp_path):
    record = make_record()
    csv_path, json_path = write_exchange(tmp_path / "r.csv", record)
    assert json_path.name == "r.json"
    back = read_exchange(csv_path)
    np.testing.assert_allclose(back.time_s, record.time_s, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.angle_rad, record.angle_rad, rtol=1e-11, atol=1e-15)
    np.testing.assert_allclose(back.table_m, record.table_m, rtol=1e-8)
    np.testing.assert_array_equal(back.tach_indices, np.arange(0, 500, 100))
    assert back.meta == record.meta
    assert back.sample_rate_hz == pytest.approx(1000.0)


def write(tmp_path, csv_text, meta=None):
    path = tmp_path / "x.csv"
    path.write_text(csv_text)
    path.with_suffix(".json").write_text(json.dumps(meta or {"experiment": "free_decay"}))
    return path


def test_missing_column_is_named(tmp_path):
    path = write(tmp_path, "time_s,angle\n0,1\n0.1,2\n")
    with pytest.raises(ExchangeFormatError, match="angle_rad"):
        read_exchange(path)


def test_garbled_value_names_line_and_column(tmp_path):
    path = write(tmp_path, "time_s,angle_rad\n0,1\n0.1,abc\n0.2,3\n")
    with pytest.raises(ExchangeFormatError, match=r"line 3.*angle_rad.*abc"):
        read_exchange(path)


def test_a_header_without_rows_is_refused_in_one_error_and_no_warning(tmp_path):
    # found by benchmarks/fuzz.py: numpy's own warning was printed before the error
    path = write(tmp_path, "time_s,angle_rad\n")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(ExchangeFormatError, match="no data rows after the header"):
            read_exchange(path)
    assert not caught


def test_non_uniform_time_is_refused(tmp_path):
    path = write(tmp_path, "time_s,angle_rad\n0,1\n0.1,2\n0.25,3\n0.3,4\n")
    with pytest.raises(ExchangeFormatError, match="uniform"):
        read_exchange(path)


def test_a_time_jump_is_named_at_its_own_line(tmp_path):
    """One jump of 50 samples in 1000: the line where time jumps is named, with both times
    (the mean step, moved 5 % by the jump, once blamed line 3)."""
    t = np.arange(1000) * 0.001
    t[600:] += 0.05
    rows = "".join(f"{ti:.6f},0.1\n" for ti in t)
    path = write(tmp_path, "time_s,angle_rad\n" + rows)
    with pytest.raises(ExchangeFormatError, match=r"line 602: time_s jumps from 0\.599 to "
                                                   r"0\.65 s .*the record's is 0\.001 s"):
        read_exchange(path)


def test_extra_columns_are_ignored(tmp_path):
    path = write(tmp_path, "note,time_s,angle_rad,other\nx,0,1,9\ny,0.1,2,9\n")
    record = read_exchange(path)
    np.testing.assert_array_equal(record.angle_rad, [1, 2])


@pytest.mark.parametrize(
    "meta, field",
    [({"experiment": "spin"}, "experiment"),
     ({"experiment": "forced"}, "drive.frequency_hz"),
     ({"format_version": 2, "experiment": "free_decay"}, "format_version.*newer"),
     ({"format_version": "1", "experiment": "free_decay"}, "format_version"),
     ({"experiment": "free_decay", "rig": {"l_m": -1}}, "rig.l_m")],
)
def test_bad_sidecar_names_the_field(tmp_path, meta, field):
    path = write(tmp_path, "time_s,angle_rad\n0,1\n0.1,2\n", meta)
    with pytest.raises(ExchangeFormatError, match=field):
        read_exchange(path)


def test_missing_sidecar_says_what_to_do(tmp_path):
    path = tmp_path / "y.csv"
    path.write_text("time_s,angle_rad\n0,1\n0.1,2\n")
    with pytest.raises(ExchangeFormatError, match="--meta"):
        read_exchange(path)
