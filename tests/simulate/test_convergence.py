"""Tolerance convergence on the paper's case h after a transient."""

from __future__ import annotations

import numpy as np

from analysis.model import Model, paper_case
from analysis.simulate import SimulationSettings, simulate


def _run(model: Model, rtol: float) -> np.ndarray:
    result = simulate(
        model, 0.1,
        settings=SimulationSettings(
            duration_s=2.0, fs_hz=1000, skip_s=10.0, rtol=rtol, atol=rtol * 1e-2,
        ),
    )
    assert result.ok
    return result.theta


def test_halving_the_tolerance_changes_little_and_errors_shrink_with_it():
    rig, drive = paper_case("h").dimensional()
    model = Model(rig, drive)
    assert np.abs(_run(model, 1e-9) - _run(model, 5e-10)).max() < 1e-6
    reference = _run(model, 1e-13)
    errors = [np.abs(_run(model, rtol) - reference).max() for rtol in (1e-7, 1e-9, 1e-11)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[1] < 1e-6
