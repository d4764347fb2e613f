"""Proposing a term when no named cause explains a record (issue 15, item 6).

The library and the selection are tested on equation-error problems that numpy makes, with
a known sparse term hidden in correlated noise; the whole proposal on forced records of
the independent reference simulator (``reference``), one with a cubic hairspring
at the pivot (an effect outside the named causes) and clean ones; and on an impact decay of
that simulator with a softening pivot spring.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import replace

import numpy as np
import pytest
from scipy import stats

from analysis.discrepancy.analyze import proposed_terms
from analysis.discrepancy.term_proposal import (
    CONTACT_EXPONENTS,
    HELDOUT_BLOCKS,
    EquationError,
    ProposedTerm,
    contact_library,
    flight_library,
    propose_terms,
    select_terms,
    weak_flight,
)
from analysis.extensions import ModelSpec
from analysis.identify.forced import (
    ForcedModel,
    fit_model,
    forced_data,
    record_segments,
    smoothed_states,
)
from analysis.packed import P
from analysis.record_loaders import load_record
from reference.decays import draw_effect_decay
from reference.forced_records import draw_forced_case, write_forced_case
from reference.unregistered import draw_unregistered_case
from tests.tolerance import Z_95, Z_999

SAMPLE_RATE_HZ = 200.0  # a low-passed flight residual, decimated: what the selection sees
DURATION_S = 30.0


def _swing(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Times, a swing of two incommensurate tones and its rate, and the packed vector of a
    drive at a third frequency (the flight library reads the drive's phase from it)."""
    t = np.arange(round(DURATION_S * SAMPLE_RATE_HZ)) / SAMPLE_RATE_HZ
    w1, w2 = rng.uniform(12.0, 16.0), rng.uniform(30.0, 40.0)
    a1, a2, p1, p2 = rng.uniform(0.1, 0.25), rng.uniform(0.02, 0.05), *rng.uniform(0, 6, 2)
    theta = a1 * np.sin(w1 * t + p1) + a2 * np.sin(w2 * t + p2) - rng.uniform(0.0, 0.1)
    rate = a1 * w1 * np.cos(w1 * t + p1) + a2 * w2 * np.cos(w2 * t + p2)
    packed = np.zeros(P.SIZE)
    packed[P.OMEGA_DRIVE] = 2 * math.pi * rng.choice([2.0, 10.0]) * rng.uniform(0.97, 1.03)
    packed[P.PHASE0] = rng.uniform(0, 2 * math.pi)
    packed[P.SHAFT_L] = 0.05
    packed[P.BARRIER] = 1.0
    return t, theta, rate, packed


def _correlated_noise(rng: np.random.Generator, n: int, rms: float) -> np.ndarray:
    """Noise correlated over a few samples, as a smoothed second derivative leaves it."""
    raw = np.convolve(rng.normal(size=n + 8), np.hanning(9), mode="valid")
    return rms * raw / raw.std()


def _standard_error(term: ProposedTerm) -> float:
    """The standard error behind a term's 95 % interval (Student's t over the blocks): a
    test over many seeds checks 4 of them, not the interval a twentieth of draws miss."""
    return (term.ci95[1] - term.ci95[0]) / 2.0 / float(stats.t.isf(0.025, HELDOUT_BLOCKS - 1))


def _left_by_own_terms(library, column: np.ndarray) -> np.ndarray:
    """What a term leaves in a baseline's residual: the part of it that the model's own
    terms (the library's ``own``, whose coefficients the baseline fits) cannot take up."""
    own = library.columns[:, list(library.own)]
    taken, *_ = np.linalg.lstsq(own, column, rcond=None)
    return column - own @ taken


def _blocks(t: np.ndarray) -> np.ndarray:
    return np.minimum((HELDOUT_BLOCKS * t / t[-1]).astype(int), HELDOUT_BLOCKS - 1)


@pytest.mark.parametrize("seed", range(6))
def test_a_hidden_flight_term_is_found_with_its_size_and_nothing_else(seed):
    rng = np.random.default_rng([15, 6, seed])
    t, theta, rate, packed = _swing(rng)
    library = flight_library(t, theta, rate, packed)
    hidden = str(rng.choice(["theta^3", "sign(theta')", "theta'|theta'|"]))
    shown = _left_by_own_terms(library, library.columns[:, library.names.index(hidden)])
    size = rng.uniform(0.8, 1.5) * float(rng.choice([-1.0, 1.0])) / np.sqrt(np.mean(shown**2))
    residual = size * shown + _correlated_noise(rng, t.size, 2.0)
    found = select_terms(library, residual, _blocks(t))
    assert [term.term for term in found] == [hidden], (hidden, [f.sentence() for f in found])
    term = found[0]
    assert term.region == "flight"
    assert abs(term.coefficient - size) < 4.0 * _standard_error(term), (size, term.ci95)
    assert term.heldout_gain > 0.01


@pytest.mark.parametrize("seed", range(6))
def test_noise_alone_asks_for_no_term(seed):
    rng = np.random.default_rng([15, 7, seed])
    t, theta, rate, packed = _swing(rng)
    library = flight_library(t, theta, rate, packed)
    assert select_terms(library, _correlated_noise(rng, t.size, 2.0), _blocks(t)) == []
    contact = contact_library(theta, rate, packed)
    assert select_terms(contact, _correlated_noise(rng, t.size, 2.0), _blocks(t)) == []


def test_a_decay_whose_flights_no_window_fits_asks_for_no_term():
    """An 8 s impact decay (contact exponent, seed 3901 of reference/decays.py) had no
    flight a weak-form window fits wholly: the proposal raised IndexError from its empty
    blocks and the analysis failed.  No window, no flight term."""
    rng = np.random.default_rng([15, 9])
    t, theta, rate, packed = _swing(rng)
    none = np.zeros(t.size, dtype=bool)
    error = EquationError(residual=np.zeros(t.size), theta=theta, rate=rate, flight=none,
                          contact=none, window=5, lowpass=9, angle=theta, free=none,
                          model_acceleration=np.zeros(t.size))
    library, residual, blocks = weak_flight(t, error, flight_library(t, theta, rate, packed),
                                            2.0, True)
    assert library.columns.shape[0] == residual.size == blocks.size == 0
    assert select_terms(library, residual, blocks) == []


@pytest.mark.parametrize("seed", range(4))
def test_a_hidden_contact_law_is_found_as_a_penetration_power(seed):
    """A contact law other than the model's own delta^1.5, as much of it as the baseline's
    K and mu0 leave: the powers of the penetration correlate by 0.98-0.99 over a
    contact, so it is found as one power, with its sign, within one step of the
    library's exponents (a neighbouring power may stand in for it), never as damping."""
    rng = np.random.default_rng([15, 8, seed])
    t, theta, rate, packed = _swing(rng)
    packed[P.SIN_THETA_B] = math.sin(float(np.quantile(theta, 0.6)))  # 40 % in contact
    library = contact_library(theta, rate, packed)
    inside = library.columns[:, 0] > 0
    n = float(rng.choice([n for n in CONTACT_EXPONENTS if n != 1.5]))  # 1.5: the model's
    contact = replace(library, columns=library.columns[inside])
    shown = _left_by_own_terms(contact, contact.columns[:, library.names.index(f"delta^{n:g}")])
    sign = float(rng.choice([-1.0, 1.0]))
    size = sign * rng.uniform(1.5, 2.5) / np.sqrt(np.mean(shown**2))
    residual = size * shown + _correlated_noise(rng, shown.size, 2.0)
    found = select_terms(contact, residual, _blocks(t)[inside])
    assert len(found) == 1, (n, [f.sentence() for f in found])
    term = found[0]
    assert term.region == "contact" and "delta'" not in term.term, term.sentence()
    step = CONTACT_EXPONENTS.index(float(term.term.removeprefix("delta^")))
    assert abs(step - CONTACT_EXPONENTS.index(n)) <= 1, (n, term.sentence())
    assert math.copysign(1.0, term.coefficient) == sign


# Forced records of the reference simulator.  identify_forced takes 12-45 s on these
# records (the baseline's compromise with a missing term is slow to converge), over a cheap
# test's budget: the model is the baseline at the case's true rig and drive values, for
# the baseline only (the hairspring stays hidden), and its trajectory over the record is
# the project's multiple-shooting fit of the segments' states with those values held (no
# true state is handed over).
RECORD_S = 20.0


def _proposal(case):
    """The terms proposed for a case's record with its baseline at the true values."""
    record = load_record(write_forced_case(case, tempfile.mkdtemp()))
    data = forced_data(record)
    rig, drive = case.rig, case.drive
    values = {"omega_rad_s": rig.omega_rad_s, "zeta": rig.zeta,
              "K_N_per_m1.5": rig.K_N_per_m1_5, "mu0_s_per_m": rig.mu0_s_per_m,
              "drive_phase_rad": drive.phase_rad, "drive_frequency_hz": drive.frequency_hz}
    model = ForcedModel(data, ())
    segments = record_segments(data)
    fit, _ = fit_model(model, segments, [], values,
                       smoothed_states(data, segments.start, 0.0), threads=2)
    return propose_terms(data.t, data.y, data.valid, model.packed(values), fit.true_angle,
                         fit.rate)


def test_a_pivot_hairspring_is_proposed_as_a_cubic_term_of_its_size():
    case = draw_unregistered_case(7001, "pivot_hairspring", frequency_hz=2.0,
                                  duration_s=RECORD_S)
    # the reference adds -c3 theta^3 to theta'': the proposed coefficient is -c3
    truth = -case.effects["pivot_hairspring"]["c3_per_s2"]
    flight = {t.term: t for t in _proposal(case) if t.region == "flight"}
    assert "theta^3" in flight, [t.sentence() for t in flight.values()]
    cubic = flight["theta^3"]
    assert math.copysign(1.0, cubic.coefficient) == math.copysign(1.0, truth)
    assert cubic.ci95[0] < truth < cubic.ci95[1], (truth, cubic.sentence())


def test_a_clean_record_asks_for_no_term():
    case = draw_forced_case(7102, "none", frequency_hz=2.0, duration_s=RECORD_S)
    assert _proposal(case) == []


# The final model that `analyze` fitted, on 2026-11-29, to the impact decay of
# reference/decays.py with a softening pivot spring (seed 7053, the decay benchmark's draw):
# a barrier offset and a sensor zero, the spring taken up by a lower frequency (omega 13.18
# rad/s for 13.83) and a barrier 2e5 times too stiff.  Held here, the test skips the
# analysis that fits it (minutes).
SOFTENING_SEED = 7053
SOFTENING_MODEL = ModelSpec.of("barrier_offset", "sensor_offset")
SOFTENING_VALUES = {
    "theta0_rad": -0.2083544573441633, "theta_dot0_rad_s": 0.07729980991628599,
    "omega_rad_s": 13.178491705572796, "zeta": 0.0027868804042698405,
    "K_N_per_m1.5": 42501849315.925316, "mu0_s_per_m": 0.7406585379904198,
    "theta_b_rad": 0.0004566688210845611, "offset_rad": 0.002406535601694097}


@pytest.mark.slow  # the reference simulator's decay, 37 s of impacts at 500 Hz, takes most
def test_a_softening_pivot_spring_in_an_impact_decay_is_proposed_as_theta_cubed(tmp_path):
    """The impact decay's flights last half a swing and each holds one weak-form window: with
    a window of a quarter swing sliding along the flights the spring's theta^3 removed 40 %
    of the held-out squares at t 3.3 over the blocks (5.3 needed) and nothing was
    proposed; one window per flight, probed by three whitened test functions, proposes it
    alone in flight, of the spring's sign and size (within its 99.9 % interval)."""
    decay = draw_effect_decay(SOFTENING_SEED, "pivot_hairspring_softening")
    record = load_record(decay.write(tmp_path))
    terms = proposed_terms(record, SOFTENING_MODEL, SOFTENING_VALUES)
    flight = [term for term in terms if term.region == "flight"]
    assert [term.term for term in flight] == ["theta^3"], [t.sentence() for t in terms]
    truth = -decay.effect_values["c3_per_s2"]  # theta'' gains -c3 theta^3
    low, high = flight[0].ci95
    half = (high - low) / 2.0 * Z_999 / Z_95
    assert abs(flight[0].coefficient - truth) <= half, (truth, flight[0].sentence())
