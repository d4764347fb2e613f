"""The commands on the virtual rig over its real protocols (pty serial DAQ + Modbus TCP)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis.exchange import read_exchange
from drivers.sensors import FLAG_OUT_OF_RANGE
from recording.reader import open_recording
from rig.cli import main
from rig.config import default_config_path, load_config
from rig.replay import iter_sample_blocks

L_M = load_config().constants.L_m


def _sine_amplitude(t, x, frequency_hz):
    """Least-squares amplitude of a sine at a known frequency (an independent estimate)."""
    w = 2 * np.pi * frequency_hz
    design = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    coefficients, *_ = np.linalg.lstsq(design, x, rcond=None)
    return float(np.hypot(coefficients[0], coefficients[1]))


@pytest.fixture(scope="module")
def forced_recording(tmp_path_factory):
    """A short forced recording from the virtual rig, made by the command line."""
    path = tmp_path_factory.mktemp("sim") / "forced.h5"
    status = main(
        [
            "record",
            "--sim",
            "--experiment",
            "forced",
            "--drive-hz",
            "6",
            "--beta",
            "0.02",
            "--settle",
            "1.5",
            "--duration",
            "2",
            "--fs",
            "4000",
            "--notes",
            "cli test",
            "--out",
            str(path),
            "--quiet",
        ]
    )
    assert status == 0
    return path


def test_record_sim_writes_every_sample_the_drive_and_the_metadata(forced_recording):
    with open_recording(forced_recording) as rec:
        angle, table = rec.channel("angle"), rec.channel("table")
        assert rec.status().closed and rec.status().stop_reason == "completed"
        # at least settle + duration of data, nothing lost, indices consecutive
        assert len(angle) >= 3.5 * 4000
        assert angle.gaps.size == 0 and rec.status().samples_lost == 0
        np.testing.assert_array_equal(
            angle.indices, np.arange(angle.indices[0], angle.indices[-1] + 1)
        )
        np.testing.assert_array_equal(angle.indices, table.indices)
        assert angle.raw.dtype == np.int16
        # the laser sees the commanded table motion once settled (last second)
        last = slice(-4000, None)
        amplitude = _sine_amplitude(table.times_s[last], table.values[last], 6.0)
        assert amplitude == pytest.approx(0.02 * L_M, rel=0.05)
        # tach edges once per drive period
        edges = rec.pulses("tach").edge_indices
        spacing = np.diff(edges[edges > angle.indices[-1] - 4000])
        np.testing.assert_allclose(spacing, 4000 / 6.0, atol=1.0)
        drive = rec.drive_log()
        drive = drive[drive["source"] == 0]  # commanded, not read back
        assert drive["frequency_hz"][0] == 6.0
        assert drive["amplitude_m"][0] == pytest.approx(0.02 * L_M)
        assert drive["enabled"][0] == 1 and drive["enabled"][-1] == 0  # ramped to zero at the end
        info = rec.info
        assert info.experiment == "forced" and info.notes == "cli test"
        assert info.devices["daq"]["model"] == "IRDAQ-4"
        assert "Modbus TCP 127.0.0.1" in info.devices["shaker"]["where"]
        assert "[calibration.angle]" in info.config_toml
        assert info.rig["L_m"] == L_M
        assert info.calibrations["angle"]["law"] == "potentiometer"


def test_export_round_trip_gives_back_the_recorded_samples(forced_recording, tmp_path, capsys):
    out = tmp_path / "forced.csv"
    assert main(["export", str(forced_recording), "--out", str(out)]) == 0
    exchanged = read_exchange(out)
    with open_recording(forced_recording) as rec:
        angle, table = rec.channel("angle"), rec.channel("table")
        edges = rec.pulses("tach").edge_indices
    # values are stored as float32; the CSV's digits give every one of them back exactly
    np.testing.assert_array_equal(exchanged.angle_rad.astype(np.float32), angle.values)
    np.testing.assert_array_equal(exchanged.table_m.astype(np.float32), table.values)
    np.testing.assert_allclose(exchanged.time_s, angle.times_s, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(
        angle.indices[exchanged.tach_indices], edges[edges >= angle.indices[0]]
    )
    meta = json.loads(out.with_suffix(".json").read_text())
    assert meta["experiment"] == "forced"
    assert meta["drive"]["frequency_hz"] == 6.0
    assert meta["rig"]["m_kg"] == 0.0326
    assert exchanged.meta.notes == "cli test"
    # the sidecar carries what a reader needs beyond the samples
    assert meta["format_version"] == 1
    assert meta["rig"]["L_m"] == L_M
    assert meta["calibrations"]["angle"]["law"] == "potentiometer"
    assert meta["samples_stored_as"] == "float32"
    assert meta["provenance"]["command_line"][:2] == ["impact-rig", "export"]
    # and the numbers are the recorded float32 samples' own digits, no conversion noise
    rows = out.read_text().splitlines()[1:]
    angle_text = [row.split(",")[1] for row in rows]
    assert max(len(text.lstrip("-").replace(".", "").lstrip("0")) for text in angle_text) <= 9
    assert [float(text) for text in angle_text[:50]] == \
        [float(str(v)) for v in angle.values[:50]]
    # an existing export is not overwritten silently
    assert main(["export", str(forced_recording), "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err


def test_free_decay_starts_just_before_the_release_and_decays(tmp_path):
    path = tmp_path / "decay.h5"
    status = main(
        [
            "record",
            "--sim",
            "--experiment",
            "free_decay",
            "--release-deg",
            "-10",
            "--pretrigger",
            "0.4",
            "--duration",
            "2.5",
            "--fs",
            "2000",
            "--out",
            str(path),
            "--quiet",
        ]
    )
    assert status == 0
    with open_recording(path) as rec:
        angle = rec.channel("angle")
        assert rec.info.experiment == "free_decay"
    held = np.radians(-10)
    moved = np.flatnonzero(np.abs(angle.values - held) > 0.005)[0]
    # the pretrigger (0.4 s) of the held pendulum comes before the motion, counted from the
    # release itself (the file starts at a block boundary: up to a block more)
    assert 0.39 * 2000 <= moved <= 0.43 * 2000
    assert np.all(np.abs(angle.values[: moved - 10] - held) < 0.003)
    # then it swings through zero to about the mirror angle (small damping)
    after = angle.values[moved:]
    assert after.max() == pytest.approx(-held, rel=0.1)


def test_impact_decay_is_recorded_fast_enough_to_resolve_the_impact(tmp_path):
    """At the impact-decay default (20 kHz) the first impact's peak penetration matches the
    Hertz oracle of docs/MODEL.md section 4 (linearised contact, mu0 = 0 bound)."""
    path = tmp_path / "impacts.h5"
    status = main(
        [
            "record",
            "--sim",
            "--experiment",
            "impact_decay",
            "--release-deg",
            "-10",
            "--duration",
            "1.0",
            "--out",
            str(path),
            "--quiet",
        ]
    )
    assert status == 0
    with open_recording(path) as rec:
        assert rec.sample_rate_hz("angle") == 20_000.0
        angle = rec.channel("angle").values.astype(float)
    c = load_config().constants
    theta0 = np.radians(10)
    omega2 = c.g_m_s2 / c.L_m
    entry_speed = c.l_m * np.sqrt(2 * omega2 * (1 - np.cos(theta0)))  # energy, no damping
    m_eff = c.m_kg * c.L_m**2 / c.l_m**2
    K = 4 / 3 * 2.0e6 * np.sqrt(c.R_m)  # the virtual rig's barrier: the paper's E
    delta_max = (5 * m_eff * entry_speed**2 / (4 * K)) ** 0.4
    peak = angle.max()  # the first impact is the deepest
    noise = load_config().virtual.noise_rad
    # mu0 > 0 only lowers the peak (the oracle is a bound); the sensor noise may add to it
    assert 0.8 * delta_max / c.l_m < peak <= 1.02 * delta_max / c.l_m + 5 * noise


def test_sweep_marks_every_step_and_per_step_export_has_the_step_drive(tmp_path):
    path = tmp_path / "sweep.h5"
    status = main(
        [
            "sweep",
            "--sim",
            "--sweep",
            "frequency",
            "--start",
            "4",
            "--stop",
            "5",
            "--steps",
            "2",
            "--amplitude-mm",
            "0.8",
            "--settle",
            "0.5",
            "--dwell",
            "1.0",
            "--fs",
            "2000",
            "--out",
            str(path),
            "--quiet",
        ]
    )
    assert status == 0
    with open_recording(path) as rec:
        steps = rec.sweep_steps()
        drive = rec.drive_log()
        drive = drive[drive["source"] == 0]  # commanded, not read back
    assert steps["frequency_hz"].tolist() == [4.0, 5.0, 4.0]
    assert steps["direction"].tolist() == [1, 1, -1]
    assert steps["complete"].tolist() == [1, 1, 1]
    dwell = steps["dwell_end_index"] - steps["dwell_start_index"]
    np.testing.assert_allclose(dwell, 2000, rtol=0.15)
    assert np.all(steps["dwell_start_index"] - steps["settle_start_index"] >= 0.4 * 2000)
    assert np.all(steps["settle_start_index"][1:] >= steps["dwell_end_index"][:-1])
    assert drive["frequency_hz"][:3].tolist() == [4.0, 5.0, 4.0]
    out = tmp_path / "sweep.csv"
    assert main(["export", str(path), "--out", str(out), "--per-step"]) == 0
    for k, frequency in enumerate((4.0, 5.0, 4.0)):
        record = read_exchange(tmp_path / f"sweep_step{k:02d}.csv")
        assert record.meta.drive["frequency_hz"] == frequency
        spacing = np.diff(record.tach_indices)
        np.testing.assert_allclose(spacing, 2000 / frequency, atol=1.0)
    # the whole sweep in one file claims no one frequency: its sidecar lists the steps,
    # and reading it as one forced record is refused with the way out
    whole = tmp_path / "whole.csv"
    assert main(["export", str(path), "--out", str(whole)]) == 0
    meta = json.loads(whole.with_suffix(".json").read_text())
    assert "frequency_hz" not in (meta.get("drive") or {})
    assert [s["frequency_hz"] for s in meta["sweep_steps"]] == [4.0, 5.0, 4.0]
    starts = [s["dwell_start_s"] for s in meta["sweep_steps"]]
    assert starts == sorted(starts) and all(s["complete"] for s in meta["sweep_steps"])
    with pytest.raises(ValueError, match="--per-step"):
        read_exchange(whole)


def test_laser_readings_beyond_its_range_are_recorded_flagged_and_replayed(tmp_path):
    # a rig file whose laser measures only +-0.5 mm: the 0.9 mm table motion leaves it
    limit_m = 5e-4
    text = default_config_path().read_text(encoding="utf-8")
    narrow = text.replace(
        "measuring_range_m = [-0.05, 0.05]", f"measuring_range_m = [{-limit_m}, {limit_m}]"
    )
    assert narrow != text
    config = tmp_path / "narrow_laser.toml"
    config.write_text(narrow, encoding="utf-8")
    path = tmp_path / "flags.h5"
    arguments = ["record", "--sim", "--config", str(config), "--experiment", "forced"]
    arguments += ["--drive-hz", "6", "--beta", "0.02", "--settle", "0.5", "--duration", "1"]
    arguments += ["--fs", "2000", "--out", str(path), "--quiet"]
    assert main(arguments) == 0
    with open_recording(path) as rec:
        table, angle = rec.channel("table"), rec.channel("angle")
        out_of_range = (table.flags & FLAG_OUT_OF_RANGE) != 0
        # values are stored as read (float32), the flag beside them
        beyond = np.abs(table.values) > limit_m * (1 + 1e-6)
        within = np.abs(table.values) < limit_m * (1 - 1e-6)
        assert beyond.sum() > 0.1 * len(table) and within.sum() > 0.1 * len(table)
        assert out_of_range[beyond].all() and not out_of_range[within].any()
        assert not angle.flags.any()
        replayed = np.concatenate([block.flags for block in iter_sample_blocks(rec, "table")])
        np.testing.assert_array_equal(replayed, table.flags)
