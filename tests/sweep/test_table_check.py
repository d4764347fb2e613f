"""The table channel checks a drive cause across a sweep as on a single record: the laser's
measurements of the table's amplitude error on the steps with a table channel combine into
one shared size, and a size fitted from the angle that contradicts it is refused at the
screening and disqualified after the fit.  Sweeps of the independent reference simulator
(scipy; never the project's integrator) of three short steps: one with the table amplitude
off its stated value (and the same without its laser), one clean."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import pytest

from analysis.discrepancy.policy import DEFAULT_POLICY
from analysis.extensions import BASELINE, ModelSpec
from analysis.identify.result import Estimate
from analysis.sweep.causes import SweepModelFits, SweepSteps, table_sizes
from analysis.sweep.fit import sweep_data
from reference.sweeps import draw_sweep

SHORT = {"up_steps": 2, "settle_s": 1.0, "dwell_s": 2.5}
AMPLITUDE = ModelSpec.of("excitation_amplitude")


def _steps(data) -> SweepSteps:
    """The selection's steps over ``data``, only as far as its table checks read them."""
    return SweepSteps(SimpleNamespace(data=data), None, {}, [], 1, DEFAULT_POLICY)


@pytest.fixture(scope="module")
def amplitude_error():
    generated = draw_sweep(11, "excitation_amplitude", parameter="amplitude", laser=True,
                           **SHORT)
    return generated.truth.causes["excitation_amplitude"]["eps"], sweep_data(generated.sweep)


def test_the_steps_measurements_combine_into_one_size_holding_the_truth(amplitude_error):
    eps, data = amplitude_error
    combined = table_sizes(data)["eps"]
    assert combined.contains(eps)
    each = [d.drive.measured_sizes()["eps"] for d in data.steps]
    assert len(each) == 3
    assert combined.half_width < min(e.half_width for e in each)


def test_a_fitted_size_the_laser_contradicts_is_disqualified_and_one_it_holds_is_not(
        amplitude_error):
    eps, data = amplitude_error
    steps = _steps(data)
    fitted = SimpleNamespace(values={"eps": 0.0}, estimates={"eps": Estimate(0.0, (-1e-3, 1e-3))})
    why = steps.disqualification(AMPLITUDE, fitted)
    assert why is not None and why.startswith("eps = 0 where the table channel measured")
    held = SimpleNamespace(values={"eps": eps},
                           estimates={"eps": Estimate(eps, (eps - 1e-3, eps + 1e-3))})
    assert steps.disqualification(AMPLITUDE, held) is None


def test_a_screened_size_the_laser_found_absent_is_not_fitted_further():
    data = sweep_data(draw_sweep(12, "none", parameter="amplitude", laser=True, **SHORT).sweep)
    steps = _steps(data)
    steps.beside = {"excitation_amplitude": SimpleNamespace(
        values={"eps": 0.05}, estimates={"eps": Estimate(0.05, (0.045, 0.055))})}
    why = steps.refused(SweepModelFits(BASELINE, None), "excitation_amplitude")
    assert why is not None and why.startswith("eps = 0.05 where the table channel measured")


def test_a_sweep_without_a_table_channel_is_not_checked(amplitude_error):
    _, with_laser = amplitude_error
    sweep = with_laser.sweep
    data = sweep_data(replace(sweep, steps=tuple(
        replace(s, record=replace(s.record, table_m=None)) for s in sweep.steps)))
    assert table_sizes(data) == {}
    fitted = SimpleNamespace(values={"eps": 0.05},
                             estimates={"eps": Estimate(0.05, (0.045, 0.055))})
    assert _steps(data).disqualification(AMPLITUDE, fitted) is None
