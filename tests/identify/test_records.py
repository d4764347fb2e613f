"""The record object and its loaders: exchange files in, the fields the fits rely on out."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.exchange import ExchangeMeta, ExchangeRecord, write_exchange
from analysis.records import Record, RecordFormatError, load_record, register_loader


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


def test_loader_registry_dispatches_on_suffix(tmp_path):
    def fake_loader(path, meta):
        return Record(np.arange(3.0), np.zeros(3), "free_decay", source=str(path))

    register_loader(".testrec", fake_loader)
    assert load_record(tmp_path / "x.testrec").source.endswith("x.testrec")
    with pytest.raises(RecordFormatError, match="unknown file type"):
        load_record(tmp_path / "x.unknown")


def test_inconsistent_arrays_are_refused():
    with pytest.raises(RecordFormatError, match="equal length"):
        Record(np.arange(3.0), np.zeros(4), "free_decay")
    with pytest.raises(RecordFormatError, match="experiment"):
        Record(np.arange(3.0), np.zeros(3), "spin_up")
