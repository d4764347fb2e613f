"""``impact-rig simulate`` end to end: a real subprocess writing files read back by the reader."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import h5py
import numpy as np

from analysis.exchange import read_exchange
from analysis.model import Model, paper_case
from analysis.simulate import SimulationSettings, simulate
from rig.cli import main


def _impact_rig(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        # the installed console script's entry, run in a fresh interpreter
        [
            sys.executable,
            "-c",
            "import sys; from rig.cli import main; sys.exit(main())",
            "simulate",
            *args,
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_quickstart_case_h_writes_the_exchange_format(tmp_path):
    out = tmp_path / "case_h.csv"
    done = _impact_rig(
        "--case", "h", "--skip", "10", "--duration", "2", "--fs", "2000", "--out", str(out)
    )
    assert done.returncode == 0, done.stderr
    assert "contacts" in done.stdout and str(out) in done.stdout
    record = read_exchange(out)
    assert record.meta.experiment == "forced"
    assert record.time_s.size == 4000 and math.isclose(record.sample_rate_hz, 2000.0)
    rig, drive = paper_case("h").dimensional()
    assert math.isclose(record.meta.drive["frequency_hz"], 10.0)
    assert math.isclose(record.meta.drive["amplitude_m"], drive.amplitude_m, rel_tol=1e-12)
    # tach: one pulse per period, on the sample nearest drive phase 0 (time_s = k / f)
    pulses = record.tach_indices
    assert pulses.size == 20
    assert np.all(np.diff(pulses) == 200)
    phase = (2 * np.pi * drive.frequency_hz * record.time_s[pulses]) % (2 * np.pi)
    assert np.all(np.minimum(phase, 2 * np.pi - phase) <= np.pi * drive.frequency_hz / 2000.0)
    # table channel is the drive, x_t = A sin(Omega t), in phase with the tach
    expected_table = drive.amplitude_m * np.sin(2 * np.pi * drive.frequency_hz * record.time_s)
    assert np.abs(record.table_m - expected_table).max() < 1e-9 * drive.amplitude_m + 1e-12
    # the angle is the model's, after the transient rounded to whole periods
    direct = simulate(
        Model(rig, drive), -0.3, 0.0,
        settings=SimulationSettings(duration_s=2.0, fs_hz=2000, skip_s=10.0),
    )
    assert np.abs(record.angle_rad - direct.theta).max() < 1e-9


def test_measurement_model_and_hdf5_output(tmp_path):
    out = tmp_path / "decay.h5"
    status = main(
        [
            "simulate",
            "--experiment",
            "free_decay",
            "--theta0",
            "0.1",
            "--duration",
            "5",
            "--fs",
            "1000",
            "--noise-rad",
            "1e-3",
            "--quantization-rad",
            "2e-4",
            "--seed",
            "3",
            "--param",
            "zeta=0.01",
            "--out",
            str(out),
        ]
    )
    assert status == 0
    with h5py.File(out) as handle:
        angle = handle["angle_rad"][:]
        time_s = handle["time_s"][:]
        meta = json.loads(handle.attrs["metadata"])
        assert "tach" not in handle
    assert meta["experiment"] == "free_decay" and meta["simulation"]["rig"]["zeta"] == 0.01
    assert time_s.size == 5000 and time_s[1] == 1e-3
    # quantized to the step, noise of the requested size around the model angle
    assert np.allclose(angle / 2e-4, np.round(angle / 2e-4), atol=1e-6)
    reference = simulate(
        Model(Model().rig.with_values(zeta=0.01), barrier=False), 0.1,
        settings=SimulationSettings(duration_s=5, fs_hz=1000),
    )
    residual = angle - reference.theta
    assert 0.9e-3 < residual.std() < 1.1e-3
    assert abs(residual.mean()) < 1e-4


def test_bad_parameter_is_a_clear_error_with_the_valid_names(tmp_path, capsys):
    done = _impact_rig("--param", "L_mm=46", "--out", str(tmp_path / "x.csv"))
    assert done.returncode == 2
    assert "unknown parameter(s) L_mm" in done.stderr and "L_m" in done.stderr
    assert "Traceback" not in done.stderr
    assert not (tmp_path / "x.csv").exists()
    for args, message in (
        (["--case", "z"], "unknown paper case"),
        (["--experiment", "forced"], "needs a drive"),
        (["--case", "h", "--experiment", "free_decay"], "forced case"),
        (["--param", "zeta"], "expected NAME=VALUE"),
        (["--param", "zeta=-1"], "zeta"),
        (["--cause", "gremlins"], "unknown cause"),
    ):
        assert main(["simulate", *args, "--out", str(tmp_path / "x.csv")]) == 2
        assert message in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()


def test_cause_parameter_switches_the_cause_on(tmp_path):
    out = tmp_path / "friction.csv"
    status = main(
        [
            "simulate",
            "--experiment",
            "free_decay",
            "--theta0",
            "0.05",
            "--duration",
            "20",
            "--fs",
            "200",
            "--param",
            "Tc_N_m=2e-5",
            "--param",
            "zeta=0",
            "--out",
            str(out),
        ]
    )
    assert status == 0
    record = read_exchange(out)
    assert record.meta.extra["simulation"]["extensions"] == {"coulomb_friction": {"Tc_N_m": 2e-5}}
    # dry friction stops the pendulum: the last seconds are exactly constant
    tail = record.angle_rad[-200:]
    assert np.all(tail == tail[0])
