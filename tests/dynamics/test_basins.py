"""Basins of attraction: attractor identification and the basin map."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.dynamics import NO_ATTRACTOR, basins_of_attraction, identify_attractors, plot_basins
from analysis.dynamics.basins import identify_attractor_groups
from analysis.model import Drive, Model, RigParameters, paper_case
from analysis.simulate import SimulationSettings, simulate
from tests.dynamics.integrators import iterate_map
from tests.dynamics.reference_systems import HENON_CLASSIC, henon_map

K = 64


def test_orbits_are_grouped_by_the_attractor_they_lie_on():
    rng = np.random.default_rng(3)
    period_one_a = np.tile([0.1, 1.0], (K, 1))
    period_one_b = np.tile([-0.3, 2.0], (K, 1))
    cycle = np.array([[0.0, -1.0], [0.2, 0.5], [-0.1, 1.5]])
    period_three = cycle[np.arange(K) % 3]
    shifted_three = cycle[(np.arange(K) + 1) % 3]  # same cycle entered one period later
    henon = iterate_map(henon_map, [0.1, 0.1], HENON_CLASSIC, 2 * K, transient=100)
    orbits = [period_one_a, period_three, period_one_b, henon[:K], shifted_three, henon[K:]]
    orbits.append(period_one_a + 1e-9 * rng.normal(size=(K, 2)))
    theta = np.array([o[:, 0] for o in orbits])
    theta_dot = np.array([o[:, 1] for o in orbits])
    ok = np.ones(len(orbits), dtype=bool)
    theta[2, 5] = np.nan  # a run that stopped: no attractor
    labels, attractors = identify_attractors(theta, theta_dot, ok=ok)
    assert labels.tolist() == [0, 1, NO_ATTRACTOR, 2, 1, 2, 0]
    assert [a.name for a in attractors] == ["period-1", "period-3", "chaotic"]
    assert attractors[1].points.shape == (3, 2)
    assert attractors[0].basin_fraction == pytest.approx(2 / 7)


def test_two_distinct_period_one_attractors_get_distinct_names():
    theta = np.array([np.full(K, 0.1), np.full(K, 0.5)])
    theta_dot = np.zeros((2, K)) + 1.0
    labels, attractors = identify_attractors(theta, theta_dot)
    assert labels.tolist() == [0, 1]
    assert [a.name for a in attractors] == ["period-1", "period-1 (2)"]


def test_linear_oscillator_has_one_basin_at_its_steady_state():
    rig = RigParameters(zeta=0.05)
    model = Model(rig, Drive(amplitude_m=0.002 * rig.L_m, frequency_hz=10.0), barrier=False)
    basins = basins_of_attraction(
        model,
        np.linspace(-0.05, 0.05, 5),
        np.linspace(-0.5, 0.5, 4),
        transient_periods=300,
        record_periods=50,
        workers=1,
    )
    assert basins.labels.shape == (4, 5)
    assert np.all(basins.labels == 0)
    (attractor,) = basins.attractors
    assert attractor.name == "period-1"
    assert attractor.basin_fraction == 1.0


def test_basin_labels_agree_with_independent_runs(tmp_path):
    """Points of the map re-simulated on their own end on the attractor they are labelled with."""
    rig, drive = paper_case("d").dimensional()
    model = Model(rig, drive)
    theta0 = np.linspace(-0.5, 0.0, 6)
    theta_dot0 = np.linspace(-4.0, 4.0, 5)
    basins = basins_of_attraction(
        model, theta0, theta_dot0, transient_periods=200, record_periods=64
    )
    assert basins.labels.min() >= 0
    rng = np.random.default_rng(8)
    for _ in range(3):
        i, j = rng.integers(0, theta_dot0.size), rng.integers(0, theta0.size)
        period = drive.period_s
        run = simulate(
            model, theta0[j], theta_dot0[i],
            settings=SimulationSettings(
                duration_s=64 * period, fs_hz=drive.frequency_hz, skip_s=200 * period, rtol=1e-8,
                atol=1e-10,
            ),
        )
        attractor = basins.attractors[basins.labels[i, j]]
        final = np.array([run.poincare.theta[-1], run.poincare.theta_dot[-1]])
        size = np.ptp(attractor.points, axis=0) + np.abs(attractor.points).max(axis=0)
        assert np.min(np.max(np.abs(attractor.points - final) / size, axis=1)) < 0.02
    figure = plot_basins(basins, title="case d", path=tmp_path / "basins.png")
    legend = [t.get_text() for t in figure.axes[0].get_legend().get_texts()]
    assert legend[0].startswith(basins.attractors[0].name)
    assert (tmp_path / "basins.png").stat().st_size > 1000


def test_too_few_recorded_periods_are_refused():
    rig, drive = paper_case("d").dimensional()
    with pytest.raises(ValueError, match="0-1"):
        basins_of_attraction(Model(rig, drive), [0.0], [0.0], record_periods=10)


def test_progress_is_reported_up_to_the_number_of_runs():
    rig = RigParameters(zeta=0.05)
    model = Model(rig, Drive(amplitude_m=0.002 * rig.L_m, frequency_hz=10.0), barrier=False)
    reports = []
    basins_of_attraction(
        model,
        np.linspace(-0.05, 0.05, 3),
        [0.0, 0.1],
        transient_periods=20,
        record_periods=50,
        workers=1,
        progress=lambda progress: reports.append((progress.done, progress.total)),
    )
    assert reports[-1] == (6, 6)
    assert [done for done, _ in reports] == sorted(done for done, _ in reports)


def test_groups_of_orbits_are_each_identified_as_if_alone():
    henon = iterate_map(henon_map, [0.1, 0.1], HENON_CLASSIC, 3 * K, transient=100)
    cycle = np.array([[0.0, -1.0], [0.2, 0.5], [-0.1, 1.5]])
    orbits = [np.tile([0.1, 1.0], (K, 1)), henon[:K], cycle[np.arange(K) % 3],  # group 1
              henon[K : 2 * K], np.tile([0.1, 1.0], (K, 1)), henon[2 * K :],  # group 2
              cycle[(np.arange(K) + 2) % 3]]  # group 3 (group 4 is empty)
    theta = np.array([o[:, 0] for o in orbits])
    theta_dot = np.array([o[:, 1] for o in orbits])
    ok = np.ones(len(orbits), dtype=bool)
    ok[3] = False
    ends = [3, 6, 7, 7]
    together = identify_attractor_groups(theta, theta_dot, ends, ok=ok)
    for (first, stop), (labels, attractors) in zip(
        zip([0, *ends[:-1]], ends, strict=True), together, strict=True
    ):
        alone_labels, alone = identify_attractors(
            theta[first:stop], theta_dot[first:stop], ok=ok[first:stop]
        )
        assert labels.tolist() == alone_labels.tolist()
        assert [(a.name, a.basin_fraction, a.regime.label) for a in attractors] == [
            (a.name, a.basin_fraction, a.regime.label) for a in alone
        ]
        for a, b in zip(attractors, alone, strict=True):
            assert np.array_equal(a.points, b.points)
    assert together[0][0].tolist() == [0, 1, 2]
    assert together[1][0].tolist() == [NO_ATTRACTOR, 0, 1]
    assert [a.name for a in together[1][1]] == ["period-1", "chaotic"]
    assert together[3][0].size == 0 and together[3][1] == ()


def test_large_orbits_are_matched_by_a_tree_to_the_same_attractors(monkeypatch):
    henon = iterate_map(henon_map, [0.1, 0.1], HENON_CLASSIC, 4 * K, transient=100)
    theta = np.array([henon[k * K : (k + 1) * K, 0] for k in range(4)])
    theta_dot = np.array([henon[k * K : (k + 1) * K, 1] for k in range(4)])
    every_pair = identify_attractors(theta, theta_dot)
    monkeypatch.setattr("analysis.dynamics.basins.BRUTE_FORCE_PAIRS", 0)  # a tree always
    by_tree = identify_attractors(theta, theta_dot)
    assert every_pair[0].tolist() == by_tree[0].tolist()
    assert by_tree[0][:3].tolist() == [0, 0, 0]  # matched through the tree
    assert [a.name for a in every_pair[1]] == [a.name for a in by_tree[1]]
