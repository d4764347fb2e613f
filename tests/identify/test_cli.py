"""``impact-rig identify`` end to end on real exchange files written to a temporary folder."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from analysis.exchange import ExchangeMeta, ExchangeRecord, write_exchange
from reference.oracle import free_decay
from rig.cli import main

MODEL_KEYS = {"L_m", "omega_rad_s", "zeta", "theta0_rad"}


@pytest.fixture
def decay_csv(tmp_path):
    t, theta = free_decay(0.12, 0.015, 0.25, duration_s=10.0, fs_hz=300.0)
    theta = theta + np.random.default_rng(4).normal(0.0, 5e-4, t.size)
    meta = ExchangeMeta("free_decay", rig={"m_kg": None, "l_m": None, "R_m": None, "g": 9.81})
    path, _ = write_exchange(tmp_path / "decay.csv", ExchangeRecord(t, theta, meta))
    return path


def test_identify_writes_the_json_report(decay_csv, tmp_path, capsys):
    out = tmp_path / "report.json"
    assert main(["identify", str(decay_csv), "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["experiment"] == "free_decay"
    assert set(report["parameters"]) >= MODEL_KEYS
    L = report["parameters"]["L_m"]
    assert L["ci95"][0] < 0.25 < L["ci95"][1]
    assert L["ci95"][0] < L["value"] < L["ci95"][1]
    printed = capsys.readouterr().out
    assert "L_m" in printed and "95% CI" in printed


def test_identify_runs_as_a_console_command(decay_csv, tmp_path):
    out = tmp_path / "report.json"
    proc = subprocess.run(
        [sys.executable, "-m", "rig.cli", "identify", str(decay_csv), "--json", str(out)],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert "zeta" in json.loads(out.read_text())["parameters"]


def test_missing_column_is_a_clear_error(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,angle_deg\n0,1\n0.1,2\n")
    (tmp_path / "bad.json").write_text(json.dumps({"experiment": "free_decay"}))
    assert main(["identify", str(bad)]) != 0
    err = capsys.readouterr().err
    assert "angle_rad" in err and "bad.csv" in err


def test_missing_sidecar_is_a_clear_error(decay_csv, capsys):
    decay_csv.with_suffix(".json").unlink()
    assert main(["identify", str(decay_csv)]) != 0
    assert "metadata file not found" in capsys.readouterr().err


def test_corrupt_hdf5_recording_is_a_clear_error(tmp_path, capsys):
    # .h5 dispatches to the recorder's loader through analysis.record_loaders; a file that is
    # not HDF5 at all must be named in a one-line error, not a traceback.
    h5 = tmp_path / "run.h5"
    h5.write_bytes(b"not an hdf5 file")
    assert main(["identify", str(h5)]) != 0
    err = capsys.readouterr().err
    assert "run.h5" in err and "HDF5" in err


def test_unfittable_record_names_the_reason(tmp_path, capsys):
    t = np.arange(2000) / 200.0
    flat = np.full(t.size, 0.01) + np.random.default_rng(0).normal(0.0, 1e-4, t.size)
    meta = ExchangeMeta("free_decay", rig={})
    path, _ = write_exchange(tmp_path / "flat.csv", ExchangeRecord(t, flat, meta))
    assert main(["identify", str(path)]) != 0
    assert "no oscillation" in capsys.readouterr().err


def test_several_free_decays_are_pooled(tmp_path):
    paths = []
    for k in range(2):
        t, theta = free_decay(0.1 + 0.03 * k, 0.015, 0.25, duration_s=8.0, fs_hz=300.0)
        theta = theta + np.random.default_rng(k).normal(0.0, 5e-4, t.size)
        meta = ExchangeMeta("free_decay", rig={"g": 9.81})
        paths.append(write_exchange(tmp_path / f"d{k}.csv", ExchangeRecord(t, theta, meta))[0])
    out = tmp_path / "pooled.json"
    assert main(["identify", *map(str, paths), "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["method"].startswith("inverse-variance pooling of 2")
    low, high = report["parameters"]["L_m"]["ci95"]
    assert low < 0.25 < high
    assert len(report["details"]["records"]) == 2


def test_impact_decay_with_length_and_damping_held_from_a_free_decay(decay_csv, tmp_path,
                                                                    capsys):
    # the independent reference simulator (scipy DOP853 with events), not the project's
    from reference.simulator import Pendulum, TableMotion, simulate_reference

    truth = Pendulum(m_kg=0.0326, l_m=0.05, L_m=0.25, zeta=0.015, K_n=3e5, mu0_s_per_m=0.5)
    t = np.arange(round(4.0 * 3000.0)) / 3000.0
    theta = simulate_reference(truth, TableMotion(), -0.3, 0.0, t).theta_rad
    angle = theta + np.random.default_rng(3).normal(0.0, 2e-4, t.size)
    meta = ExchangeMeta("impact_decay", rig={"m_kg": 0.0326, "l_m": 0.05, "R_m": 0.0095,
                                             "g": 9.81})
    path, _ = write_exchange(tmp_path / "impacts.csv", ExchangeRecord(t, angle, meta))
    out = tmp_path / "impacts_params.json"  # impacts.json is the input's sidecar: refused
    assert main(["identify", str(path), "--free-decay", str(decay_csv), "--json", str(out)]) == 0
    report = json.loads(out.read_text())["parameters"]
    assert "ci95" not in report["L_m"]  # held from the free decay, not fitted
    # and the printed summary says so in words, while a fitted one prints its interval
    printed = {line.split()[0]: line for line in capsys.readouterr().out.splitlines()
               if line.startswith("  ")}
    assert printed["L_m"].endswith("(not determined by this record)")
    assert "95% CI [" in printed["K_N_per_m1.5"]
    assert report["L_m"]["value"] == pytest.approx(0.25, rel=2e-3)
    low, high = report["K_N_per_m1.5"]["ci95"]
    assert low < 3e5 * 1.01 and high > 3e5 * 0.99  # held L is itself uncertain (~1e-3)
    assert report["R_m"]["value"] == 0.0095
    assert {"E_Pa", "mu0_s_per_m", "theta_b_rad", "theta0_rad"} <= set(report)


def test_simulated_hdf5_is_identified_like_its_csv(tmp_path, capsys):
    # `simulate --out FILE.h5` writes a recording (the recorder's layout); identify reads it.
    h5 = tmp_path / "decay.h5"
    assert main([
        "simulate", "--experiment", "free_decay", "--theta0", "0.1", "--param", "L_m=0.1",
        "--param", "zeta=0.02", "--duration", "5", "--fs", "400", "--noise-rad", "3e-4",
        "--seed", "5", "--out", str(h5),
    ]) == 0
    out = tmp_path / "report.json"
    assert main(["identify", str(h5), "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["experiment"] == "free_decay"
    L = report["parameters"]["L_m"]
    assert L["ci95"][0] < 0.1 < L["ci95"][1]
    assert abs(L["value"] - 0.1) < 1e-3


def test_missing_data_file_is_named(tmp_path, capsys):
    assert main(["identify", str(tmp_path / "absent.csv")]) != 0
    assert "absent.csv: file not found" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("hold", "message"),
    [("L_m=-0.05", "held L_m = -0.05"), ("zeta=nan", "held zeta = nan")],
)
def test_impossible_held_value_is_named(decay_csv, tmp_path, capsys, hold, message):
    meta = ExchangeMeta("impact_decay", rig={"g": 9.81})
    t = np.arange(3000) / 1000.0
    path, _ = write_exchange(tmp_path / "imp.csv", ExchangeRecord(t, np.sin(10 * t), meta))
    assert main(["identify", str(path), "--hold", hold]) != 0
    assert message in capsys.readouterr().err


def test_free_decay_option_refuses_a_record_of_another_experiment(tmp_path, capsys):
    meta = ExchangeMeta("impact_decay", rig={"g": 9.81})
    t = np.arange(3000) / 1000.0
    path, _ = write_exchange(tmp_path / "imp.csv", ExchangeRecord(t, np.sin(10 * t), meta))
    assert main(["identify", str(path), "--free-decay", str(path)]) != 0
    assert "its experiment is impact_decay, not free_decay" in capsys.readouterr().err


def test_report_into_a_missing_folder_is_refused_before_fitting(decay_csv, tmp_path, capsys):
    out = tmp_path / "no_such_folder" / "report.json"
    assert main(["identify", str(decay_csv), "--json", str(out)]) != 0
    captured = capsys.readouterr()
    assert "does not exist" in captured.err and "identifying" not in captured.err
