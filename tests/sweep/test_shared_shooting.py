"""Multiple shooting over several records with shared parameters: a parameter of one part
(a step's drive phase) has a Jacobian column that is zero outside its part, and the
columns of different parts' parameters, differenced in one run together, are the columns
each would get alone; segments are never linked across parts."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from analysis.extensions import ModelSpec
from analysis.identify.forced import record_segments, smoothed_states
from analysis.identify.shooting import FreeParameter, ShootingProblem
from analysis.sweep.fit import SweepModel, joined, sweep_data, sweep_parameters
from analysis.sweep.load import load_sweep
from reference.sweeps import generate_sweep


@pytest.fixture(scope="module")
def two_steps(tmp_path_factory) -> tuple:
    """A two-step sweep of the reference simulator, its data and joined segments."""
    path = Path(tmp_path_factory.mktemp("sweep")) / "two.h5"
    generate_sweep(path, seed=3, betas=(0.02, 0.03), settle_s=1.0, dwell_s=2.5)
    data = sweep_data(load_sweep([path]))
    segments = joined(data, [record_segments(d) for d in data.steps])
    return data, segments


def test_a_part_parameter_column_is_its_own_run_and_zero_elsewhere(two_steps) -> None:
    data, segments = two_steps
    model = SweepModel(data, ("barrier_offset",))
    start = {"omega_rad_s": 14.3, "zeta": 0.008, "K_N_per_m1.5": 1.7e5, "mu0_s_per_m": 0.8,
             "theta_b_rad": 0.0}
    free = sweep_parameters(data, ModelSpec(model.causes), start, start, phase_free=True)
    assert [p.part for p in free if "@" in p.name] == [0, 1]
    problem = model.problem(segments, free, {}, threads=1)
    states = np.concatenate([smoothed_states(d, s.start, 0.0)
                             for d, s in zip(data.steps, segments.each, strict=True)])
    u = np.zeros(len(free))
    hs = np.array([1e-6, 1e-5])
    theta, ends = problem.run(problem.values_of(u), states)
    r = problem.residuals(theta, ends, states)
    jac = problem._jacobian(u, states, r, theta, ends, hs)
    # the same parameters as if every part saw them: each column from its own run
    alone = ShootingProblem(problem.t, problem.y, problem.valid, problem.sigma,
                            segments.segments, problem.packs,
                            [replace(p, part=None) for p in free], {},
                            part_of_segment=segments.part, rate_scale=problem.rate_scale,
                            threads=1, robust=problem.robust)
    reference = alone._jacobian(u, states, r, theta, ends, hs)
    np.testing.assert_allclose(jac.shared, reference.shared, rtol=0, atol=1e-12)
    rows = problem.row_part
    for i, p in enumerate(free):
        if p.part is not None:
            assert np.any(jac.shared[rows == p.part, i] != 0)
            assert np.all(jac.shared[rows != p.part, i] == 0)
    # no link joins the first step's last segment to the second step's first
    last = segments.each[0].count - 1
    assert not segments.segments.linked[last] and last not in problem.links


def test_parts_out_of_order_or_linked_across_are_refused(two_steps) -> None:
    data, segments = two_steps
    model = SweepModel(data)
    free = [FreeParameter("zeta", 0.008, 1e-6)]
    linked = replace(segments.segments, linked=np.ones(segments.segments.count, dtype=bool))
    with pytest.raises(ValueError, match="linked to the next part"):
        ShootingProblem(data.t, data.y, data.valid, 1e-3, linked, model.packs(), free, {},
                        part_of_segment=segments.part)
    with pytest.raises(ValueError, match="in order"):
        ShootingProblem(data.t, data.y, data.valid, 1e-3, segments.segments, model.packs(),
                        free, {}, part_of_segment=segments.part[::-1])


def test_a_step_whose_own_omega_strays_is_named_and_started_from_its_record(two_steps) -> None:
    # one pendulum swings in every step: a step whose fit alone put omega far from the
    # steps' median found another basin, and its own phase and states are no start
    from types import SimpleNamespace

    from analysis.sweep.fit import STRAY_OMEGA, _strays

    data, _ = two_steps
    said: list[str] = []

    def alone(omega: float) -> SimpleNamespace:
        return SimpleNamespace(short_fit=SimpleNamespace(values={"omega_rad_s": omega}))

    median = 13.7
    near, far = median * (1 + 0.5 * STRAY_OMEGA), median * (1 + 2 * STRAY_OMEGA)
    assert _strays(data, [alone(near), alone(far)], median, said.append) == {1}
    assert len(said) == 1 and f"step {data.numbers[1]} alone put omega" in said[0]
    assert _strays(data, [alone(median), alone(near)], median, said.append) == set()
