"""The period map's Jacobians from the forward sensitivities (continuation's default) against
its central differences and against central differences of the scipy reference simulator
(``tests/reference/simulator.py``, which shares no code with the integrator), on the paper's
case (g) period-2 orbit, which strikes the barrier twice per orbit."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.dynamics.model_parameters import model_with, parameter_value
from analysis.dynamics.period_map import PeriodMap
from analysis.dynamics.periodic_orbits import find_periodic_orbit
from analysis.model import Model, paper_case
from tests.dynamics.baseline_reference import reference_image

BETA = 0.022


def _case_g(**values: float) -> Model:
    rig, drive = paper_case("g").dimensional()
    model = Model(rig, drive)
    for name, value in {"beta": BETA, **values}.items():
        model = model_with(model, name, value)
    return model


@pytest.fixture(scope="module")
def orbit():
    """The case (g) period-2 orbit (found with the differences, so that nothing of the
    sensitivities enters where it lies)."""
    model = _case_g()
    found = find_periodic_orbit(PeriodMap(model, "beta", 2, jacobians="differences"), BETA,
                                np.array([-0.12, -0.7]))
    assert found.residual < 1e-10
    return model, found.state


def _reference_jacobian(model: Model, state: np.ndarray, steps: np.ndarray) -> np.ndarray:
    columns = []
    for j, step in enumerate(steps):
        dx = np.zeros(2)
        dx[j] = step
        columns.append((reference_image(model, state + dx, 2)
                        - reference_image(model, state - dx, 2)) / (2.0 * step))
    return np.column_stack(columns)


def test_sensitivity_monodromy_matches_both_difference_routes(orbit):
    model, state = orbit
    exact = PeriodMap(model, "beta", 2)
    differences = PeriodMap(model, "beta", 2, jacobians="differences")
    assert exact.jacobian_method == "sensitivities"
    ours = exact.linearise(BETA, state)
    theirs = differences.linearise(BETA, state, richardson=True)
    assert ours.image == pytest.approx(theirs.image, abs=1e-9)  # run at rtol 1e-12, 1e-11
    scale = np.max(np.abs(theirs.jacobian))
    assert np.max(np.abs(ours.jacobian - theirs.jacobian)) < 1e-7 * scale
    assert np.max(np.abs(ours.multipliers - theirs.multipliers)) < 1e-7
    # d P / d beta: A1 moves with beta (A = beta L), the chain rule through the packing
    assert np.allclose(ours.parameter_derivative, theirs.parameter_derivative,
                       rtol=1e-7, atol=1e-7 * np.max(np.abs(theirs.parameter_derivative)))
    # the reference simulator: central differences at two steps, the gap estimating theirs
    steps = np.array([1e-5, 1e-5 * exact.drive_rate(BETA)])
    fine = _reference_jacobian(model, state, steps)
    coarse = _reference_jacobian(model, state, 2.0 * steps)
    estimate = np.max(np.abs(fine - coarse))
    assert estimate < 1e-5 * scale  # the check below means something
    assert np.max(np.abs(ours.jacobian - fine)) < 1e-6 * scale + 3.0 * estimate
    reference_multipliers = np.sort_complex(np.linalg.eigvals(fine))
    assert np.allclose(np.sort_complex(ours.multipliers), reference_multipliers, atol=1e-5)
    assert np.all(np.abs(ours.multipliers) < 1.0)  # the stable orbit a long run settles on


@pytest.mark.parametrize("name", ["f_drive_hz", "theta_b_rad", "mu0_s_per_m"])
def test_parameter_derivative_through_the_period_and_the_contact(orbit, name):
    # f_drive_hz moves the map's end time (the field there times dT / df), theta_b_rad the
    # contact surface (saltation with its own derivative), mu0 only the contact force
    model, state = orbit
    start = parameter_value(model, name)
    ours = PeriodMap(model, name, 2).linearise(start, state)
    theirs = PeriodMap(model, name, 2, jacobians="differences").linearise(start, state,
                                                                          richardson=True)
    size = np.max(np.abs(theirs.parameter_derivative))
    assert size > 0.0
    assert np.max(np.abs(ours.parameter_derivative - theirs.parameter_derivative)) < 1e-6 * size


def test_coulomb_friction_falls_back_to_differences_saying_so(orbit):
    _, state = orbit
    model = _case_g().with_extension("coulomb_friction", Tc_N_m=1e-6)
    period_map = PeriodMap(model, "beta", 2)
    assert period_map.jacobian_method == "differences"
    assert "Coulomb friction" in period_map.jacobian_note
    assert np.all(np.isfinite(period_map.linearise(BETA, state).jacobian))
