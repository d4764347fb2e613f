"""Diagrams read from files: a sweep recorded on the virtual rig, and files that hold none."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from analysis.dynamics.diagram_files import DiagramFileError, read_diagrams
from analysis.hdf5_records import load_hdf5_steps
from rig.cli import main
from rig.config import load_config


@pytest.fixture(scope="module")
def amplitude_sweep(tmp_path_factory):
    """1 mm, 2 mm and back to 1 mm at 10 Hz on the virtual rig, 1 s of dwell per step."""
    path = tmp_path_factory.mktemp("sweep") / "sweep.h5"
    status = main(["sweep", "--sim", "--sweep", "amplitude", "--start", "1", "--stop", "2",
                   "--steps", "2", "--drive-hz", "10", "--settle", "0.3", "--dwell", "1.0",
                   "--fs", "2000", "--out", str(path), "--quiet"])
    assert status == 0
    return path


def test_recorded_sweep_gives_each_direction_its_steps_betas_and_phase_zero_angles(
    amplitude_sweep,
):
    up, down = read_diagrams(amplitude_sweep, "beta")
    L_m = load_config().constants.L_m
    assert (up.direction, down.direction) == ("recorded up", "recorded down")
    np.testing.assert_allclose(up.parameter, [1e-3 / L_m, 2e-3 / L_m], rtol=1e-12)
    np.testing.assert_allclose(down.parameter, [1e-3 / L_m], rtol=1e-12)
    steps = load_hdf5_steps(amplitude_sweep)
    for row, record in zip([*up.theta, *down.theta], steps, strict=True):
        points = row[np.isfinite(row)]
        assert 8 <= points.size <= 11  # one per drive period of the 1 s dwell
        # the pendulum's angle at drive phase 0: inside the range the dwell's samples cover
        assert record.angle_rad.min() <= points.min() and points.max() <= record.angle_rad.max()
    # the two 1 mm steps are different stretches of the record, not one read twice
    assert not np.allclose(up.theta[0][:8], down.theta[0][:8])
    by_frequency = read_diagrams(amplitude_sweep, "f_drive_hz")
    assert [d.parameter_name for d in by_frequency] == ["f_drive_hz", "f_drive_hz"]
    np.testing.assert_allclose(by_frequency[0].parameter, [10.0, 10.0])


def test_files_without_a_diagram_are_refused_with_the_reason(amplitude_sweep, tmp_path):
    with pytest.raises(DiagramFileError, match="drawn over beta or f_drive_hz"):
        read_diagrams(amplitude_sweep, "zeta")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as handle:
        handle.attrs["format"] = "something else"
    with pytest.raises(DiagramFileError, match="'something else' holds no diagram"):
        read_diagrams(other, "beta")
    text = tmp_path / "notes.h5"
    text.write_text("not HDF5")
    with pytest.raises(DiagramFileError, match="cannot be read as HDF5"):
        read_diagrams(text, "beta")
