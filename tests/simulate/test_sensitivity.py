"""Forward sensitivities of the compiled integrator against independent routes.

The derivatives of (theta, theta') with respect to the initial state and to packed
parameters (``analysis.simulate.sensitivity``) are compared with central differences of
the scipy reference simulator (``tests/reference/simulator.py``, which shares no code with
the integrator), on a run in free flight, one with several impacts, one that barely
touches the barrier and a chaotic one.  A central difference has its own error: it is
estimated from two step sizes (the difference of the two quotients, whose truncation
error falls fourfold from one to the other, plus the reference's own rounding noise,
which grows as the step shrinks), and the agreement asked for is 1e-6 of the column's
size plus three times that estimate; each case also asserts that its differences were
good to 1e-5, so that the check means something.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
import pytest

from analysis.model import (
    Drive,
    Model,
    RigParameters,
    acceleration_partials,
    coefficients,
    paper_case,
    sliding_acceleration,
    surface_force,
)
from analysis.packed import P
from analysis.simulate.sensitivity import (
    SensitivitySettings,
    segment_sensitivities,
    simulate_sensitivities,
)
from reference.simulator import Pendulum, TableMotion, simulate_reference

AGREEMENT = 1e-6  # of a column's largest value over the compared times
DIFFERENCE_GOOD_ENOUGH = 1e-5  # the central differences' estimated error, same scale
REFERENCE_RTOL = 1e-12


@dataclass(frozen=True)
class Case:
    """A run: the model, its start, the times compared, and the columns checked (each with
    its central-difference step)."""

    model: Model
    theta0: float
    theta_dot0: float
    duration_s: float
    steps: dict[str, float]
    contacts: tuple[int, int]  # the run's contact count lies in [low, high]


def _reference(model: Model, theta0: float, theta_dot0: float, t: np.ndarray,
               shift: dict[str, float]) -> np.ndarray:
    """theta, theta' of the reference simulator at t, the model's parameters moved by
    ``shift`` (keyed by the sensitivity columns' names)."""
    rig = model.rig
    packed = model.pack()
    pendulum = Pendulum(
        m_kg=rig.m_kg, l_m=rig.l_m, L_m=rig.L_m, zeta=rig.zeta,
        K_n=packed[P.K] + shift.get("K", 0.0),
        mu0_s_per_m=packed[P.MU0] + shift.get("MU0", 0.0),
        c_N_s_per_m=packed[P.C_VISCOUS] + shift.get("C_VISCOUS", 0.0),
        theta_b_rad=packed[P.THETA_B] + shift.get("THETA_B", 0.0),
        barrier=model.barrier,
    )
    table = TableMotion(amplitude_m=model.drive.amplitude_m + shift.get("A1", 0.0),
                        frequency_hz=model.drive.frequency_hz)
    run = simulate_reference(pendulum, table, theta0 + shift.get("theta0", 0.0),
                             theta_dot0 + shift.get("theta_dot0", 0.0), t,
                             rtol=REFERENCE_RTOL, atol=1e-14)
    return np.stack([run.theta_rad, run.theta_dot_rad_s])


def _central(case: Case, t: np.ndarray, name: str, step: float) -> np.ndarray:
    ahead = _reference(case.model, case.theta0, case.theta_dot0, t, {name: step})
    behind = _reference(case.model, case.theta0, case.theta_dot0, t, {name: -step})
    return (ahead - behind) / (2.0 * step)


def _rig(case_name: str) -> tuple[RigParameters, Drive]:
    return paper_case(case_name).dimensional()


def _cases() -> dict[str, Case]:
    rig_d, drive_d = _rig("d")
    rig_i, drive_i = _rig("i")
    # the free swing from -0.1 rad comes back to 0.0976 rad: a barrier at 0.0975 rad is
    # touched by about 1e-4 rad
    grazing_rig = replace(rig_d, theta_b_rad=0.0975)
    return {
        "flight": Case(Model(rig=rig_d, drive=drive_d, barrier=False), 0.1, 0.5, 0.4,
                       {"theta0": 1e-4, "theta_dot0": 1e-3, "A1": 1e-7}, (0, 0)),
        "impacts": Case(Model(rig=rig_d), -0.4, 0.0, 0.6,
                        {"theta0": 1e-4, "theta_dot0": 1e-3, "K": 40.0, "MU0": 1e-3,
                         "THETA_B": 2e-6}, (3, 20)),
        "near_grazing": Case(Model(rig=grazing_rig), -0.1, 0.0, 0.35,
                             {"theta0": 1e-7, "K": 1.0, "THETA_B": 1e-7}, (1, 1)),
        "chaotic": Case(Model(rig=rig_i, drive=drive_i), -0.2, 0.0, 0.6,
                        {"theta0": 1e-6, "K": 3.0, "A1": 1e-8}, (2, 20)),
    }


CASES = _cases()


def _compared(case: Case, settings: SensitivitySettings | None = None):
    t = np.linspace(0.0, case.duration_s, 13)[1:]
    parameters = tuple(name for name in case.steps if name not in ("theta0", "theta_dot0"))
    settings = settings or SensitivitySettings(parameters=parameters, rtol=1e-11, atol=1e-13)
    return t, simulate_sensitivities(case.model.pack(), case.theta0, case.theta_dot0, t,
                                     settings=settings)


def _check_column(case: Case, t: np.ndarray, run, column: str, step: float,
                  agreement: float = AGREEMENT) -> None:
    """Our column against the reference's central difference with ``step``, within 1e-6 of
    its size plus three times the difference's estimated error (over the run, for theta and
    theta' each): the gap between the quotients with ``step`` and twice it, which bounds the
    finer one's error (its truncation error is a quarter of the coarser one's, its rounding
    noise at most twice)."""
    ours = run.jacobian[:, :, run.columns.index(column)].T  # (theta or theta', time)
    fine = _central(case, t, column, step)
    coarse = _central(case, t, column, 2.0 * step)
    scale = np.max(np.abs(fine), axis=1, keepdims=True)
    estimate = np.max(np.abs(fine - coarse), axis=1, keepdims=True)
    assert np.all(estimate <= DIFFERENCE_GOOD_ENOUGH * scale), (column, estimate / scale)
    gap = np.abs(ours - fine)
    assert np.all(gap <= agreement * scale + 3.0 * estimate), (column, gap / scale)


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_sensitivities_agree_with_central_differences_of_the_reference(name):
    case = CASES[name]
    t, run = _compared(case)
    assert run.status == "ok"
    assert case.contacts[0] <= run.n_contacts <= case.contacts[1]
    for column, step in case.steps.items():
        _check_column(case, t, run, column, step)


def test_chaotic_sensitivities_grow():
    """The chaotic case's derivatives grow over the run, as a positive exponent makes them."""
    _, run = _compared(CASES["chaotic"])
    state_block = run.jacobian[-1, :, :2]  # the identity at the start
    assert np.linalg.norm(state_block) > 30.0 * math.sqrt(2.0)


KELVIN_VOIGT = Case(Model(rig=_rig("d")[0]).with_extension("contact_damping_law",
                                                          c_N_s_per_m=2.0),
                    -0.4, 0.0, 0.6,
                    {"theta0": 1e-4, "C_VISCOUS": 1e-3, "THETA_B": 2e-6, "K": 40.0}, (3, 20))


def test_kelvin_voigt_sensitivities_cross_its_jump():
    """Kelvin-Voigt's force jumps to c deltadot at entry: there the saltation matrix is not
    the identity, and without it the derivatives would be off by far more than this.  Its
    force is clamped at 0 well before the exit (the c deltadot pull): a kink of the field
    that the run's steps cross."""
    case = KELVIN_VOIGT
    t, run = _compared(case)
    assert run.status == "ok" and run.n_contacts >= 3
    for column, step in case.steps.items():
        _check_column(case, t, run, column, step)


def _saltation(model: Model, theta: float, theta_dot: float, inside: float) -> np.ndarray:
    """The general saltation matrix I + (f+ - f-) g_y / (g_y f-) of the surface
    g = theta - theta_b at an entry state, f- the free flight's field there and f+ the
    contact's field ``inside`` rad beyond the surface (its limit as that falls to 0), both
    from the model's own equation."""
    p = model.pack()
    t = 0.0
    free = sliding_acceleration(t, theta, theta_dot, coefficients(p, False), 1.0, 0.0)
    contact = sliding_acceleration(t, theta + inside, theta_dot, coefficients(p, True), 1.0,
                                   0.0)
    f_minus = np.array([theta_dot, free])
    f_plus = np.array([theta_dot, contact])
    g_y = np.array([1.0, 0.0])
    return np.eye(2) + np.outer(f_plus - f_minus, g_y) / (g_y @ f_minus)


@pytest.mark.parametrize("c", [0.0, 2.0])
def test_saltation_at_a_real_contact_entry(c):
    """At the reference run's contact entries the general saltation matrix tends to the
    identity for the Hunt-Crossley law (its force vanishes at the surface like delta^1.5),
    and to the jump the integrator applies (``surface_force``) for Kelvin-Voigt."""
    model = KELVIN_VOIGT.model if c else CASES["impacts"].model
    rig = model.rig
    pendulum = Pendulum(m_kg=rig.m_kg, l_m=rig.l_m, L_m=rig.L_m, zeta=rig.zeta,
                        K_n=rig.K_N_per_m1_5, mu0_s_per_m=0.0 if c else rig.mu0_s_per_m,
                        c_N_s_per_m=c)
    run = simulate_reference(pendulum, TableMotion(), -0.4, 0.0, np.array([0.6]))
    entries = run.events_of("contact_entry")
    assert len(entries) >= 3
    k = coefficients(model.pack(), True)
    for event in entries:
        th, om = event.theta_rad, event.theta_dot_rad_s
        jump = k[9] * surface_force(math.cos(th), om, k)  # K_GAIN: the contact gain
        kernel = np.array([[1.0, 0.0], [-jump / om, 1.0]])
        deviations = [np.max(np.abs(_saltation(model, th, om, inside) - kernel))
                      for inside in (1e-6, 1e-8, 1e-10)]
        if c == 0.0:
            assert jump == 0.0
            # delta^1.5: ten thousandfold closer, a millionfold smaller
            assert deviations[2] < 1e-5 * deviations[0]
        else:
            assert abs(jump / om) > 10.0  # a real jump, not rounding
        assert deviations[2] < 1e-6 * max(1.0, abs(jump / om))


def test_partials_agree_with_central_differences_of_the_equation():
    """``acceleration_partials`` (what the sensitivities integrate) against central
    differences of the model's own equation, in contact and in flight, with every term on."""
    rig, drive = _rig("d")
    model = Model(rig=rig, drive=replace(drive, h2=0.1, phi2_rad=0.4),
                  ).with_extension("quadratic_drag", c2_per_rad=0.02).with_extension(
                      "contact_damping_law", c_N_s_per_m=0.5)
    p = model.pack()
    p[P.PHASE0] = 0.3
    d_p = np.empty(P.SIZE)
    for t, th, om in ((0.013, 0.004, 2.0), (0.021, 0.01, -0.3), (0.05, -0.3, 1.5)):
        k = coefficients(p, True)
        d_th, d_om, d_t = acceleration_partials(t, th, om, k, 1.0, 0.0, d_p)

        def f(t_=t, th_=th, om_=om, q=p):
            return sliding_acceleration(t_, th_, om_, coefficients(q, True), 1.0, 0.0)

        def central(g, x, h):
            return (g(x + h) - g(x - h)) / (2.0 * h)

        assert d_th == pytest.approx(central(lambda x: f(th_=x), th, 1e-7), rel=1e-6, abs=1e-6)
        assert d_om == pytest.approx(central(lambda x: f(om_=x), om, 1e-6), rel=1e-6, abs=1e-6)
        assert d_t == pytest.approx(central(lambda x: f(t_=x), t, 1e-7), rel=1e-6, abs=1e-6)
        for index in (P.OMEGA2, P.TWO_ZETA_OMEGA, P.INV_L, P.CONTACT_GAIN, P.SHAFT_L, P.K,
                      P.EXPONENT, P.MU0, P.C_VISCOUS, P.SIN_THETA_B, P.C2, P.OMEGA_DRIVE,
                      P.A1, P.A2, P.PHI2, P.PHASE0):
            def moved(x, i=index):
                q = p.copy()
                q[i] = x
                return f(q=q)

            step = 1e-5 * max(abs(p[index]), 1e-2)
            assert d_p[index] == pytest.approx(central(moved, p[index], step), rel=1e-5,
                                               abs=1e-6), P(index).name


def test_results_do_not_depend_on_threads():
    """Runs in a pool of threads give the same derivatives, to the bit, as one by one."""
    case = CASES["impacts"]
    alone = [_compared(case)[1].jacobian for _ in range(2)]
    with ThreadPoolExecutor(max_workers=4) as pool:
        pooled = list(pool.map(lambda _: _compared(case)[1].jacobian, range(4)))
    for jacobian in alone[1:] + pooled:
        assert np.array_equal(jacobian, alone[0])


def test_bad_settings_are_refused_by_name():
    with pytest.raises(ValueError, match="'KAPPA' is not a packed entry"):
        SensitivitySettings(parameters=("KAPPA",))
    with pytest.raises(ValueError, match="rtol"):
        SensitivitySettings(rtol=0.0)
    friction = Model().with_extension("coulomb_friction", Tc_N_m=1e-4)
    with pytest.raises(ValueError, match="Coulomb friction"):
        simulate_sensitivities(friction.pack(), 0.1, 0.0, np.array([0.1]))


def test_segments_are_runs_of_their_own():
    """``segment_sensitivities`` gives each segment what a run of its own from its start
    gives, its columns 0 and 1 its own start state's, to the bit."""
    case = CASES["impacts"]
    p = case.model.pack()
    t0 = np.array([0.0, 0.2, 0.35])
    state0 = np.array([[-0.4, 0.0], [0.1, -2.0], [-0.2, 3.0]])
    times = [t0[k] + np.linspace(0.01, 0.15, 8) for k in range(3)]
    settings = SensitivitySettings(parameters=("K", "THETA_B"), rtol=1e-9, atol=1e-11)
    th, om, jacobian, status = segment_sensitivities(
        p, t0, state0, np.concatenate(times), np.array([0, 8, 16, 24]), settings=settings)
    assert np.all(status == 0)
    for k in range(3):
        alone = simulate_sensitivities(p, *state0[k], times[k], t0=t0[k], settings=settings)
        rows = slice(8 * k, 8 * k + 8)
        assert np.array_equal(th[rows], alone.theta)
        assert np.array_equal(om[rows], alone.theta_dot)
        assert np.array_equal(jacobian[rows], alone.jacobian)
