"""Each cause declares what a real rig can have; an estimate outside it, or on a bound of the
fit, is no explanation, however much it gains."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from analysis.discrepancy.forced_judges import table_contradiction
from analysis.discrepancy.selection import Verdict, choose
from analysis.extensions import CAUSES, ModelSpec, cause
from analysis.identify.forced import forced_data
from analysis.identify.result import Estimate
from analysis.record_loaders import load_record
from harness.hidden_cause import SHOWS_IN, draw_case
from reference.cause_sizes import ResponseScale, draw_cause_values
from reference.forced_records import draw_forced_case, write_forced_case
from tests.tolerance import within_999


def test_every_plausible_range_lies_inside_the_fits_bounds_around_the_neutral_value():
    for c in CAUSES.values():
        for spec in c.parameters:
            low, high = spec.plausible or (spec.lower, spec.upper)
            assert spec.lower <= low <= spec.default <= high <= spec.upper, (c.name, spec)


def test_an_estimate_outside_the_range_or_on_a_bound_is_named_with_its_value():
    k3 = cause("sensor_nonlinearity")
    assert k3.implausibility({"k3": -0.06}) is None
    assert "outside what a real rig can have" in k3.implausibility({"k3": 7.0})
    assert "sits on the fit's bound 10" in k3.implausibility({"k3": 10.0})
    # a zero lower bound at the neutral value is where an absent effect rests, not a stop
    assert cause("coulomb_friction").implausibility({"Tc_N_m": 0.0}) is None
    # log-scaled parameters: a value many decades above the lower bound is not on it
    exponent = cause("contact_exponent")
    assert exponent.implausibility({"n": 1.8, "K_n": 1e5}) is None
    assert "n = 0.5" in exponent.implausibility({"n": 0.5, "K_n": 1e5})
    assert "not a number" in cause("sensor_offset").implausibility({"offset_rad": math.nan})


def _verdict(name: str, bic: float, implausible: str | None = None) -> Verdict:
    return Verdict(model=ModelSpec.of(name), information_criterion_delta=bic,
                   heldout_rms_baseline=1.0, heldout_rms_extended=0.5, rms_baseline=1.0,
                   rms_extended=0.5, implausible=implausible)


def test_an_implausible_best_fit_is_passed_over_and_says_why():
    bent = _verdict("sensor_nonlinearity", 500.0, "k3 = 7 is outside ...")
    right = _verdict("coulomb_friction", 80.0)
    assert not bent.earns_keep and "no explanation: k3 = 7" in bent.why
    assert choose([bent, right]).model == ModelSpec.of("coulomb_friction")
    assert choose([bent]) is None
    assert replace(bent, implausible=None).earns_keep


@pytest.mark.parametrize("seed", range(0, 400, 20))
def test_the_sizes_the_reference_draws_are_plausible(seed):
    # every size the test generators draw as a real cause must pass, whatever the record
    rng = np.random.default_rng(seed)
    amplitude = rng.uniform(0.02, 0.7)
    rate = rng.uniform(10.0, 70.0) * amplitude  # swing speed, rad/s
    scale = ResponseScale(amplitude_rad=amplitude, mean_speed_rad_s=2 / math.pi * rate,
                          mean_square_speed=rate**2 / 2,
                          mean_cube_speed=4 / (3 * math.pi) * rate**3,
                          impact_speed_m_s=rng.uniform(0.02, 0.6))
    L = rng.uniform(0.03, 0.3)
    for name in CAUSES:
        values = draw_cause_values(
            rng, name, scale, m_kg=rng.uniform(0.01, 0.2), l_m=0.95 * L, L_m=L,
            zeta=rng.uniform(0.002, 0.03), omega_rad_s=math.sqrt(9.81 / L),
            K_N_per_m1_5=rng.uniform(5e4, 2e6), mu0_s_per_m=rng.uniform(0.2, 2.0),
            noise_rad=rng.uniform(2e-4, 3e-3), gravity_torque_N_m=rng.uniform(5e-3, 0.3),
            at_least=rng.uniform(0.0, 0.9))
        assert cause(name).implausibility(values) is None, (name, values)
    for experiment, names in SHOWS_IN.items():
        for name in (n for n in names if n != "none"):
            case = draw_case(seed, experiment, name)
            assert cause(name).implausibility(case.values) is None, (experiment, name, case)


def test_a_drive_size_the_table_channel_measured_otherwise_is_no_explanation(tmp_path):
    case = draw_forced_case(7333, "excitation_distortion", frequency_hz=10.0, laser=True,
                            duration_s=10.0)
    data = forced_data(load_record(write_forced_case(case, tmp_path)))
    measured = data.drive.measured_sizes()
    h2 = case.causes["excitation_distortion"]["h2"]
    # each inside its 99.9 % interval (eps is 0: the table runs at the stated amplitude)
    assert within_999(measured["h2"], h2), (measured["h2"], h2)
    assert within_999(measured["eps"], 0.0), measured["eps"]

    def fit(**sizes: tuple[float, float]) -> SimpleNamespace:  # value, 95 % half-width
        return SimpleNamespace(estimates={k: Estimate(v, (v - w, v + w))
                                          for k, (v, w) in sizes.items()})

    model = ModelSpec.of("excitation_distortion")
    amplitude = ModelSpec.of("excitation_amplitude")
    assert table_contradiction(data, model, fit(h2=(1.05 * h2, 1e-4))) is None
    assert table_contradiction(data, model, fit(h2=(0.0, 1.0))) is None  # not known
    why = table_contradiction(data, model, fit(h2=(0.5 * h2, 1e-4)))
    assert "h2 = " in why and "table channel measured" in why
    assert "eps = 0.1" in table_contradiction(data, amplitude,
                                              fit(eps=(0.1, 0.01)))
    # a screening is judged only on the sizes the channel found absent: its rough harmonic
    # may stand off the measured one, but no amplitude error is no amplitude error
    assert table_contradiction(data, model, fit(h2=(0.5 * h2, 1e-4)), absent_only=True) is None
    assert "eps = 0.1" in table_contradiction(data, amplitude,
                                              fit(eps=(0.1, 0.01)), absent_only=True)
    # causes the table does not measure, and a record without a table channel: no verdict
    zero = ModelSpec.of("sensor_offset")
    assert table_contradiction(data, zero, fit(offset_rad=(0.1, 0.01))) is None
    no_laser = replace(data, drive=replace(data.drive, table=None))
    assert table_contradiction(no_laser, model, fit(h2=(0.5 * h2, 1e-4))) is None
