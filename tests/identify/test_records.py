"""The record object and its loaders: exchange files in, the fields the fits rely on out."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.exchange import ExchangeMeta, ExchangeRecord, write_exchange
from analysis.record_loaders import load_record
from analysis.records import Record
from recording.errors import RecordFormatError


def test_exchange_csv_becomes_a_record(tmp_path):
    t = np.arange(100) / 50.0
    tach = np.zeros(100)
    tach[[10, 60]] = 1
    meta = ExchangeMeta(
        "forced", rig={"m_kg": 0.03, "l_m": 0.05, "R_m": None, "g": 9.8},
        drive={"frequency_hz": 2.0, "amplitude_m": 0.01},
    )
    write_exchange(tmp_path / "r.csv",
                   ExchangeRecord(t, np.sin(t), meta, table_m=0.01 * np.sin(t), tach=tach))
    record = load_record(tmp_path / "r.csv")
    assert record.experiment == "forced"
    assert record.sample_rate_hz == pytest.approx(50.0)
    assert list(record.tach_indices) == [10, 60]
    assert record.gravity_m_s2 == 9.8
    rig = record.rig_parameters()
    assert (rig.m_kg, rig.l_m, rig.g_m_s2) == (0.03, 0.05, 9.8)
    assert rig.R_m == 0.0095  # unknown in the file: the model's default
    drive = record.model_drive()
    assert (drive.frequency_hz, drive.amplitude_m) == (2.0, 0.01)


def test_an_unknown_file_type_is_refused_naming_the_known_ones(tmp_path):
    with pytest.raises(RecordFormatError, match=r"x.unknown: unknown file type '.unknown'; "
                       r"expected one of \['.csv', '.h5', '.hdf5'\]"):
        load_record(tmp_path / "x.unknown")


def test_inconsistent_arrays_are_refused():
    with pytest.raises(RecordFormatError, match="equal length"):
        Record(np.arange(3.0), np.zeros(4), "free_decay")
    with pytest.raises(RecordFormatError, match="experiment"):
        Record(np.arange(3.0), np.zeros(3), "spin_up")


def test_simulated_hdf5_keeps_drive_table_and_tach(tmp_path):
    from rig.cli import main

    h5 = tmp_path / "forced.h5"
    assert main(["simulate", "--case", "d", "--duration", "1", "--fs", "1000",
                 "--out", str(h5)]) == 0
    record = load_record(h5)
    assert record.experiment == "forced"
    assert record.drive["frequency_hz"] == 10.0
    # tach marks drive phase 0 (time 0 and every 1/f = 100 samples): the table is at zero there
    assert list(record.tach_indices) == list(range(0, 1000, 100))
    assert np.max(np.abs(record.table_m[record.tach_indices])) < 1e-12
    assert np.max(np.abs(record.table_m)) == pytest.approx(record.drive["amplitude_m"], rel=1e-3)
