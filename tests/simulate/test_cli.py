"""``impact-rig simulate`` end to end: a real subprocess writing files read back by the reader."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from analysis.exchange import read_exchange
from analysis.model import Model, paper_case
from analysis.record_loaders import load_record
from analysis.simulate import SimulationSettings, simulate
from recording.reader import open_recording
from rig.cli import main
from rig.commands.simulate import build_model


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
    with open_recording(out) as recording:  # the recorder's layout, read like any recording
        angle_data = recording.channel("angle")
        info = recording.info
        assert recording.pulse_names == [] and recording.status().closed
    angle, time_s = angle_data.values.astype(float), angle_data.times_s
    assert info.experiment == "free_decay" and info.extra["simulation"]["rig"]["zeta"] == 0.01
    assert info.extra["source"] == "simulated" and info.provenance["software"]
    assert time_s.size == 5000 and time_s[1] == 1e-3
    # quantized to the step (then stored as float32, as the recorder stores values), noise of
    # the requested size around the model angle
    steps = np.round(angle / 2e-4)
    assert np.array_equal(angle_data.values, (steps * 2e-4).astype(np.float32))
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


def test_simulated_hdf5_is_a_recording_that_replays_and_exports_like_its_csv(tmp_path, capsys):
    run = ["simulate", "--case", "h", "--skip", "1", "--duration", "1", "--fs", "2000",
           "--overwrite"]
    assert main([*run, "--out", str(tmp_path / "sim.h5")]) == 0
    assert main([*run, "--out", str(tmp_path / "sim.csv")]) == 0
    assert main(["replay", str(tmp_path / "sim.h5"), "--fast"]) == 0
    assert main(["export", str(tmp_path / "sim.h5"), "--out", str(tmp_path / "back.csv")]) == 0
    direct, back = read_exchange(tmp_path / "sim.csv"), read_exchange(tmp_path / "back.csv")
    assert np.array_equal(back.time_s, direct.time_s)
    for column in ("angle_rad", "table_m"):  # the recording stores values as float32
        np.testing.assert_allclose(getattr(back, column), getattr(direct, column), rtol=2**-23,
                                   atol=1e-12)
    assert np.array_equal(back.tach_indices, direct.tach_indices)
    assert back.meta.drive == direct.meta.drive and back.meta.experiment == "forced"
    # analyze reads the recording itself as the record its export is
    record, exported = load_record(tmp_path / "sim.h5"), load_record(tmp_path / "back.csv")
    assert record.experiment == exported.experiment and record.drive == exported.drive
    assert np.array_equal(record.time_s, exported.time_s)
    assert np.array_equal(record.tach_indices, exported.tach_indices)
    for column in ("angle_rad", "table_m"):  # float32 values, written as decimal text
        np.testing.assert_allclose(getattr(record, column), getattr(exported, column),
                                   rtol=2**-23, atol=1e-12)


def test_lyapunov_spectrum_is_printed_and_written_with_its_span_and_convergence(tmp_path):
    # a linear damped swing: both exponents are -zeta omega (their sum, the divergence,
    # exactly; each up to the frame's phase wobble, ln(omega) / T)
    out = tmp_path / "decay.csv"
    done = _impact_rig("--experiment", "free_decay", "--theta0", "0.01", "--param",
                       "zeta=0.005", "--skip", "2", "--duration", "60", "--fs", "50",
                       "--lyapunov", "--out", str(out))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[1].startswith("Lyapunov spectrum (QR on the variational flow")
    assert "per natural period" in lines[1] and lines[2].startswith("  convergence: ")
    spectrum = read_exchange(out).meta.extra["simulation"]["lyapunov_spectrum"]
    model, _ = build_model(None, "free_decay", {"zeta": 0.005}, [])
    omega = model.rig.omega_rad_s
    rate = 0.005 * omega
    exponents = np.array(spectrum["exponents_per_s"])
    assert np.sum(exponents) == pytest.approx(-2.0 * rate, rel=1e-6)
    assert np.all(np.abs(exponents + rate) <= math.log(omega) / 60.0)
    # the span: the natural periods after the skipped transient, counted from its end
    period = 2.0 * math.pi / omega
    assert spectrum["period_s"] == pytest.approx(period)
    assert spectrum["from_s"] == pytest.approx(round(2.0 / period) * period)
    assert spectrum["intervals"] == round(60.0 / period)
    assert len(spectrum["standard_error_per_period"]) == 2 and spectrum["batches"] == 10
    assert f"{exponents[0]:+.4g}" in lines[1]


def test_lyapunov_refuses_coulomb_friction_in_one_line(tmp_path, capsys):
    out = tmp_path / "x.csv"
    assert main(["simulate", "--case", "h", "--duration", "0.5", "--cause",
                 "coulomb_friction", "--param", "Tc_N_m=1e-5", "--lyapunov",
                 "--out", str(out)]) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]  # after the progress line
    assert error.startswith("impact-rig simulate: error: --lyapunov: ")
    assert "Coulomb friction" in error
    assert not out.exists()
