"""Ensembles: every member equals the corresponding single run."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.model import Model, paper_case
from analysis.packed import P
from analysis.simulate import SimulationSettings, simulate_ensemble, simulate_packed


def test_parameter_sweep_members_equal_individual_runs():
    rig, drive = paper_case("h").dimensional()
    base = Model(rig, drive).pack()
    betas = np.array([0.02, 0.03, 0.114, 0.12])
    packed = np.tile(base, (betas.size, 1))
    packed[:, P.A1] = betas * rig.L_m
    packed[-1, P.OMEGA_DRIVE] *= 0.9  # another frequency: fewer Poincare samples, NaN padded
    result = simulate_ensemble(packed, [-0.2, 0.5], duration_s=3.0, skip_s=2.0, fs_hz=500.0)
    assert result.samples is not None and result.samples.shape == (4, 1500, 2)
    for i in range(betas.size):
        single = simulate_packed(
            packed[i], -0.2, 0.5,
            settings=SimulationSettings(duration_s=3.0, fs_hz=500.0, skip_s=2.0),
        )
        count = single.poincare.theta.size
        assert np.array_equal(result.poincare[i, :count, 0], single.poincare.theta)
        assert np.array_equal(result.poincare[i, :count, 1], single.poincare.theta_dot)
        assert np.all(np.isnan(result.poincare[i, count:]))
        assert np.allclose(result.poincare_t[i, :count], single.poincare.t, rtol=0, atol=1e-12)
        assert np.array_equal(result.samples[i, :, 0], single.theta)
        assert result.n_steps[i] == single.n_steps
        assert result.record_start_s[i] == single.record_start_s
        assert result.contacts[i] == single.contacts.count > 0
        assert result.status[i] == single.status
    assert result.poincare.shape[1] == 31 and np.isnan(result.poincare[-1, -1, 0])


def test_initial_state_grid_with_one_parameter_vector():
    rig, drive = paper_case("d").dimensional()
    p = Model(rig, drive).pack()
    grid = np.array([[th, om] for th in (-1.0, -0.4, 0.0) for om in (-5.0, 5.0)])
    result = simulate_ensemble(p, grid, duration_s=1.0, skip_s=5.0)
    assert result.samples is None and result.ok.all()
    for (theta0, theta_dot0), poincare in zip(grid, result.poincare, strict=True):
        single = simulate_packed(
            p, theta0, theta_dot0,
            settings=SimulationSettings(duration_s=1.0, fs_hz=10, skip_s=5.0),
        )
        assert np.array_equal(poincare[:, 0], single.poincare.theta)


def test_mismatched_shapes_are_refused():
    p = Model().pack()
    with pytest.raises(ValueError, match="rows"):
        simulate_ensemble(np.tile(p, (3, 1)), np.zeros((2, 2)), duration_s=1.0)
    with pytest.raises(ValueError, match="expected"):
        simulate_ensemble(p[:5], np.zeros(2), duration_s=1.0)
    for settings, named in (({"skip_s": -1.0}, "skip_s"), ({"fs_hz": 0.0}, "fs_hz")):
        with pytest.raises(ValueError, match=named):
            simulate_ensemble(p, np.zeros(2), duration_s=1.0, **settings)


def test_member_that_leaves_the_regime_is_nan_padded_and_named():
    rig, drive = paper_case("d").dimensional()
    p = Model(rig, drive).pack()
    result = simulate_ensemble(p, [[0.1, 0.0], [4.0, 0.0]], duration_s=1.0, fs_hz=100.0)
    assert result.status.tolist() == ["ok", "over_the_top"]
    assert np.all(np.isfinite(result.poincare[0])) and np.all(np.isfinite(result.poincare_t[0]))
    # beyond the first sample (the initial state at t = 0) the stopped member has nothing
    assert np.all(np.isnan(result.poincare[1, 1:])) and np.all(np.isnan(result.poincare_t[1, 1:]))
    assert np.all(np.isnan(result.samples[1, 1:]))
