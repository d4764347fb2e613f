"""impact-rig map as a user runs it: files, provenance, clear errors before any work, resume."""

from __future__ import annotations

import os
import re
import shutil
import signal
import socket
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from analysis.dynamics import model_at_beta
from analysis.maps import read_map
from analysis.maps.figures import draw_map
from analysis.maps.overlay import sweep_from_steps
from analysis.model import Drive, Model, RigParameters
from analysis.records import Record
from analysis.simulate import SimulationSettings, integrator, simulate
from recording.superblock import clear_writer_flags
from tests.conftest import compiled_by_the_suite
from tests.maps.conftest import TINY, assert_same_map, finite_fraction, map_main, run_map


def test_each_kind_writes_a_complete_map_with_its_provenance_and_figure(reference_maps):
    for kind, path in reference_maps.items():
        data = read_map(path)
        assert data["kind"] == kind and data["complete"]
        assert data["tasks"]["done"].all()
        assert finite_fraction(path) > 0.5  # the tiny maps stay in the model mostly
        command = data["provenance"]["command_line"]
        assert command[:3] == ["impact-rig", "map", kind]
        assert data["provenance"]["dependencies"]["numba"] != "not installed"
        assert path.with_suffix(".png").stat().st_size > 10_000
    regimes = read_map(reference_maps["regimes"])["summary"]
    assert regimes["attractors"].shape == (6,) and np.all(regimes["attractors"] >= 1)
    basins = read_map(reference_maps["basins"])
    assert basins["summary"]["label"].shape == (12,)
    assert len(basins["summary_info"]["attractors"]) >= 1


def test_a_bifurcation_sweeps_continue_from_step_to_step(reference_maps):
    traj = read_map(reference_maps["bifurcation"])["trajectories"]
    up = np.flatnonzero(traj["role"] == 0)
    ok = traj["status"][up[:-1]] == 0
    # each step of the up sweep started exactly where the step before ended
    assert np.array_equal(traj["initial"][up[1:]][ok], traj["final"][up[:-1]][ok])


@pytest.mark.parametrize(
    ("vary", "named"),
    [
        ("beta=0.02:0.6", "NAME=START:STOP:N"),
        ("beta=0.02:0.6:zero", "whole number"),
        ("beta=0.02:0.6:0", "N must be"),
        ("bta=0.02:0.6:5", "bta"),
        ("theta0=-0.5:0:5", "map basins"),
    ],
)
def test_a_bad_vary_is_refused_before_anything_runs(tmp_path, capsys, vary, named):
    out = tmp_path / "map.h5"
    status, err = map_main(capsys, "bifurcation", "--f-drive-hz", "10", "--vary", vary,
                           "--out", str(out))
    assert status == 2
    assert err.startswith("impact-rig map: error: --vary ") and named in err
    assert not out.exists() and not out.with_suffix(".png").exists()


def test_a_varied_value_that_another_setting_overrides_is_refused(tmp_path, capsys):
    out = tmp_path / "map.h5"
    status, err = map_main(
        capsys, "bifurcation", "--f-drive-hz", "10", "--param", "A_m=0.003",
        "--vary", "beta=0.02:0.2:5", "--out", str(out),
    )
    assert status == 2
    assert "--vary beta: its values do not change the model" in err
    assert not out.exists()


@pytest.mark.timeout(60)
def test_an_unreachable_scheduler_is_a_clear_error(tmp_path, capsys):
    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    out = tmp_path / "map.h5"
    status, err = map_main(capsys, *TINY["bifurcation"], "--scheduler",
                           f"tcp://127.0.0.1:{port}", "--out", str(out))
    assert status == 2
    assert f"cannot reach the Dask scheduler at tcp://127.0.0.1:{port} within 5 s" in err
    assert "Traceback" not in err
    assert not out.exists()  # nothing written for a map that could not run


def test_another_map_never_overwrites_an_existing_file(tmp_path, capsys, reference_maps):
    out = tmp_path / "map.h5"
    shutil.copy(reference_maps["bifurcation"], out)
    before = out.read_bytes()
    status, err = map_main(capsys, *TINY["bifurcation"], "--seed", "7", "--workers", "1",
                           "--out", str(out))
    assert status == 2
    assert "holds a different map (seed: 0 in the file, 7 now)" in err
    assert "--overwrite" in err
    assert out.read_bytes() == before


@pytest.mark.slow
def test_a_killed_run_resumes_to_the_same_map(tmp_path, capsys):
    args = [
        "bifurcation", "--f-drive-hz", "10", "--vary", "beta=0.06:0.14:80", "--ics", "4",
        "--transient-periods", "200", "--record-periods", "50", "--batch", "4",
        "--workers", "1",
    ]
    whole = tmp_path / "whole.h5"
    assert map_main(capsys, *args, "--out", str(whole))[0] == 0
    killed = tmp_path / "killed.h5"
    process = subprocess.Popen(
        [sys.executable, "-m", "rig.cli", "map", *args, "--out", str(killed)],
        stderr=subprocess.PIPE, text=True,
    )
    for line in process.stderr:
        found = re.search(r"map: (\d+)/(\d+) tasks", line)
        if found and 0 < int(found[1]) < int(found[2]):
            process.send_signal(signal.SIGKILL)  # no chance to close the file
            break
    process.wait(timeout=60)
    assert process.returncode == -signal.SIGKILL
    scratch = tmp_path / "inspect.h5"
    shutil.copy(killed, scratch)
    clear_writer_flags(scratch)
    with h5py.File(scratch, "r") as handle:
        done = handle["tasks/done"][...].astype(bool)
    assert 0 < done.sum() < done.size  # killed in the middle
    status, err = map_main(capsys, *args, "--out", str(killed))
    assert status == 0, err
    assert f"{done.size - done.sum()} tasks left" in err
    assert_same_map(whole, killed)
    assert len(read_map(killed)["runs"]) == 2  # both runs recorded with their provenance


def test_a_file_that_is_not_a_map_is_never_written_over(tmp_path, capsys):
    out = tmp_path / "notes.h5"
    out.write_bytes(b"lab notes, not HDF5\n" * 10)
    before = out.read_bytes()
    status, err = map_main(capsys, *TINY["bifurcation"], "--workers", "1", "--out", str(out))
    assert status == 2
    assert "is not an HDF5 map file; pass --overwrite" in err
    assert out.read_bytes() == before


def test_the_numbers_do_not_depend_on_how_the_map_is_cut_into_tasks(
    tmp_path, capsys, reference_maps
):
    for kind in ("bifurcation", "regimes"):
        out = tmp_path / f"{kind}.h5"
        args = [*TINY[kind][:-2], "--batch", "3"]  # the reference cut into other tasks
        assert map_main(capsys, *args, "--workers", "1", "--out", str(out))[0] == 0
        a, b = read_map(reference_maps[kind]), read_map(out)
        assert a["settings"]["batch"] != b["settings"]["batch"]
        for group in ("trajectories", "summary"):
            for name, values in a[group].items():
                assert values.tobytes() == b[group][name].tobytes(), (kind, group, name)


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_map_is_the_same_whether_its_process_compiled_the_integrator_or_loaded_it(
    tmp_path, reference_maps
):
    """On a fresh install the first map compiles the integrator and writes numba's cache;
    later runs and every worker load it.  Both must compute the same numbers as this
    process, whatever it compiled or loaded before (issue 20: they differed while the
    kernels let LLVM fuse multiply-adds).  On a fresh checkout run with ``-n`` the process
    that compiled the suite's kernels drew the map that compiled them (``tests/conftest.py``);
    otherwise a process with an empty cache of its own compiles them here."""
    compiled = compiled_by_the_suite()
    cache = None
    if compiled is None:
        cache = tmp_path / "numba_cache"
        env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))  # empty: compile
        compiled = tmp_path / "compiled.h5"
        result = run_map(*TINY["bifurcation"], "--workers", "1", "--quiet", "--out",
                         str(compiled), timeout=400, env=env)
        assert result.returncode == 0, result.stderr
    else:
        env = None  # the cache the suite's compiling process wrote
    assert_same_map(reference_maps["bifurcation"], compiled)
    loaded = tmp_path / "loaded.h5"
    result = run_map(*TINY["bifurcation"], "--workers", "1", "--quiet", "--out", str(loaded),
                     timeout=400, env=env)
    assert result.returncode == 0, result.stderr
    assert_same_map(reference_maps["bifurcation"], loaded)
    where = cache or Path(integrator.integrate.stats.cache_path)
    assert any(where.rglob("integrator.integrate-*.nbi"))  # the second run had a cache


def test_a_recorded_sweep_is_drawn_from_the_settled_poincare_points_of_its_steps(
    tmp_path, reference_maps
):
    base = Model(RigParameters(), Drive(amplitude_m=0.002, frequency_hz=10.0))
    steps, expected = [], []
    for beta in (0.05, 0.08, 0.05):  # up, up, down
        settings = SimulationSettings(duration_s=4.0, fs_hz=1000.0, skip_s=20.0, poincare_phase=0.0)
        result = simulate(model_at_beta(base, beta), 0.0, 0.0, settings=settings)
        time_s = result.t - result.t[0]
        tach = np.arange(0, time_s.size, 100)  # a pulse at every drive phase 0 (100 samples)
        steps.append(Record(time_s, result.theta, "forced", rig={},
                            drive={"frequency_hz": 10.0, "amplitude_m": beta * 0.046},
                            tach_indices=tach))
        # the integrator's own Poincare section over the settled (second) half: the oracle
        settled = (result.poincare.t - result.t[0] >= 2.0 - 1e-9) & (
            result.poincare.t <= result.t[-1] + 1e-9
        )
        expected.append(result.poincare.theta[settled])
    sweep = sweep_from_steps(steps, "beta")
    assert sweep.directions == ("up", "up", "down")
    np.testing.assert_allclose(sweep.values, [0.05, 0.08, 0.05], rtol=1e-12)
    for measured, oracle in zip(sweep.theta, expected, strict=True):
        np.testing.assert_allclose(measured, oracle, atol=1e-9)
    figure = draw_map(read_map(reference_maps["bifurcation"]), tmp_path / "with_sweep.png", sweep)
    assert figure.stat().st_size > 10_000
