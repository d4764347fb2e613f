"""The judges of a candidate cause on a forced record: the information criterion over the
whole record, the forecasts of held-out stretches (a paired test stretch by stretch), and,
on a chaotic record, the invariant statistics of the model's own long run."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from analysis import quantities as q
from analysis.discrepancy.forced_models import Layouts, ModelFits, as_fit_result
from analysis.discrepancy.invariants import Invariants, invariant_distance, invariants
from analysis.discrepancy.policy import DEFAULT_POLICY, SelectionPolicy
from analysis.discrepancy.selection import Verdict, information_criterion_delta, paired_gain_z
from analysis.extensions import BASELINE, ModelSpec, cause, implausibility
from analysis.identify.forced import ForcedData
from analysis.identify.intervals import Z95
from analysis.identify.result import Estimate
from analysis.identify.shooting import Segments, ShootingFit
from analysis.model_values import measured_angle, packed_from_values
from analysis.simulate import SimulationSettings, simulate_packed

MODEL_INVARIANT_SPAN = 4  # a model's invariants come from a run this many records long


def disqualification(data: ForcedData, model: ModelSpec, fit: ShootingFit,
                     policy: SelectionPolicy = DEFAULT_POLICY) -> str | None:
    """Why a fitted model explains nothing, whatever it gains, or None: values no real rig
    can have (:func:`analysis.extensions.implausibility`), or a drive the table channel
    measured otherwise."""
    return implausibility(model, fit.values) or \
        table_contradiction(data, model, fit, policy=policy)


def table_contradiction(data: ForcedData, model: ModelSpec, fit: ShootingFit, *,
                        absent_only: bool = False,
                        policy: SelectionPolicy = DEFAULT_POLICY) -> str | None:
    """Why the drive causes' sizes fitted from the angle contradict what the table channel
    measured of them (the laser watches the table itself), or None
    (:func:`table_gaps` on the record's measured drive)."""
    return table_gaps(data.drive.measured_sizes(), model, fit.estimates,
                      absent_only=absent_only, policy=policy)


def table_gaps(measured: Mapping[str, Estimate], model: ModelSpec,
               fitted_sizes: Mapping[str, Estimate], *, absent_only: bool = False,
               policy: SelectionPolicy = DEFAULT_POLICY) -> str | None:
    """Why the drive causes' sizes ``fitted_sizes`` (fitted from the angle) contradict
    ``measured`` (the table channel's measurement of them, keyed as the causes'
    parameters), or None: the two differ by the policy's ``table_z`` standard errors of
    their difference and by its ``table_tolerance`` of the larger.  A table amplitude or
    harmonic that only the angle's fit wants is another effect's stand-in: a second
    harmonic of 4e-4 was fitted beside a sensor lag where the laser measured 2e-6 +- 6e-6.

    ``absent_only`` judges only the sizes the channel found no different from none (for a
    screening, whose sizes are rough: a true 0.148 amplitude error screened at 0.21 beside
    a missing sensor zero, and its fit over the record came to 0.1474)."""
    def standard_error(e: Estimate) -> float:  # none known counts as none
        return e.half_width / Z95 if math.isfinite(e.half_width) else 0.0

    reasons = []
    for name in model.causes:
        for spec in cause(name).parameters:
            laser, fitted = measured.get(spec.name), fitted_sizes.get(spec.name)
            if laser is None or fitted is None:
                continue
            if absent_only and \
                    abs(laser.value - spec.default) > policy.table_z * standard_error(laser):
                continue
            gap = abs(fitted.value - laser.value)
            sigma = math.hypot(standard_error(fitted), standard_error(laser))
            if gap > policy.table_z * sigma and \
                    gap > policy.table_tolerance * max(abs(fitted.value), abs(laser.value)):
                reasons.append(f"{spec.name} = {fitted.value:.3g} where the table channel "
                               f"measured {laser.value:.3g} +- {laser.half_width:.2g}")
    return "; ".join(reasons) or None


def model_invariants_distance(
    data: ForcedData, measured: Invariants, model: ModelSpec, fit: ShootingFit
) -> float:
    """Distance between the record's invariants and those of the fitted model run from its
    first segment's state over MODEL_INVARIANT_SPAN times the record's length."""
    causes = model.causes
    values = fit.values
    phase = values.get(q.drive_phase_rad, data.drive.phase0_rad)
    drive = data.drive.model_drive(values.get(q.drive_frequency_hz))
    p = packed_from_values(data.rig, drive, True, values, causes, phase)
    n = MODEL_INVARIANT_SPAN * data.t.size
    sim = simulate_packed(
        p, float(fit.states[0, 0]), float(fit.states[0, 1]),
        settings=SimulationSettings(
            duration_s=n * data.dt, fs_hz=1.0 / data.dt, poincare_phase=None, rtol=1e-8, atol=1e-10,
        ),
    )
    t = np.arange(sim.theta.size) * data.dt
    theta = measured_angle(causes, values, t, np.asarray(sim.theta, dtype=float))
    if theta.size < 16:
        return math.inf
    return invariant_distance(measured, invariants(t, theta, data.drive.frequency_hz, phase))


def forecast_z(base: ShootingFit, candidate: ShootingFit, train: Segments) -> float | None:
    """The drop of the mean-square forecast error from baseline to candidate, in standard
    errors of its mean over the held-out stretches (:func:`paired_gain_z`)."""
    return paired_gain_z(base.forecast_residual, candidate.forecast_residual,
                         zip(train.fit_stop, train.stop, strict=True))


def verdict_of(
    data: ForcedData, candidate: ModelFits, base: ModelFits, lay: Layouts,
    distances: tuple[float | None, float | None] = (None, None),
    not_judged: str | None = None, policy: SelectionPolicy = DEFAULT_POLICY,
) -> Verdict:
    """Both judges' view of a candidate against the baseline (without training fits, when
    it did not pass the information criterion or a better cause was accepted first, it has
    no forecast)."""
    judged = candidate.train is not None and base.train is not None
    return Verdict(
        model=candidate.model,
        information_criterion_delta=information_criterion_delta(
            as_fit_result(base.full, BASELINE), as_fit_result(candidate.full, candidate.model),
            data.noise_rad),
        heldout_rms_baseline=base.train.forecast_rms if base.train is not None else math.nan,
        heldout_rms_extended=candidate.train.forecast_rms if judged else math.nan,
        rms_baseline=base.full.rms,
        rms_extended=candidate.full.rms,
        invariant_distance_baseline=distances[0],
        invariant_distance_extended=distances[1],
        noise_rad=data.noise_rad,
        n_heldout=int(np.count_nonzero(np.isfinite(base.train.forecast_residual)))
        if base.train is not None else 0,
        forecast_z=forecast_z(base.train, candidate.train, lay.train) if judged else None,
        not_judged=not_judged,
        implausible=disqualification(data, candidate.model, candidate.full, policy),
        policy=policy,
    )
