"""Whether a decay's model holds its parameters over the record: the final model refitted on
the large swings and on the rest, its rig's parameters compared (a ``constancy`` finding).

A model that lacks a term whose effect grows or shrinks with the swing compensates with its
own parameters, and the compromise depends on the swings it is fitted to.  A barrier on
a compliant mount (a series spring: the contact's force law stiffens less than Hertz's at
depth), fitted with a contact exponent, came out at n = 1.38 on the early, deep impacts
and 1.44 on the late, shallow ones (z = -16.6); a contact damping proportional to the
penetration rather than to its 1.5th power gave Hunt-Crossley's mu0 = 0.98 s/m on the
early impacts and 1.35 s/m on the late ones (z = -9.5).  The whole records' residuals
were white at 1.1 times their noise.  With the right model (twelve records of the
reference generator with their true causes) no parameter differed by more than 2.6
standard errors.

The rule: the record is split where the final model's swing (the largest true angle still
to come, 0 at rest) falls below SPLIT_SHARE of its largest; each part is fitted alone (the
early part from the final model's values, the late one from its states at the split), and
every parameter of the rig and the causes (not the initial states) is compared by
z = (early - late) / sqrt(se_early^2 + se_late^2), on the scale the fit works in (the log
for omega, K and the other parameters fitted as logs), with standard errors from the fits'
95 % intervals.  A finding when some z exceeds in size the two-sided FALSE_ALARM quantile
divided among the parameters compared (Bonferroni).  A parameter that ends on a bound of
its range in either part, or has no interval there, is not compared.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import stats

from analysis import quantities as q
from analysis.discrepancy.fitting import FitData, FitResult, fit, free_parameters, predict
from analysis.discrepancy.residual_reading import Finding
from analysis.dynamics.lines import FALSE_ALARM
from analysis.extensions import RecordScale
from analysis.identify.intervals import Z95

# The early part: swings above this share of the largest.  At 0.6 the early part of an
# impact decay is short (its swing falls fast): the penetration-proportional damping above
# gave z = -2.1 there, -9.5 at 0.45.
SPLIT_SHARE = 0.45
MIN_SWINGS = 2  # each part lasts at least this many of the model's periods
STATES = (q.theta0_rad, q.theta_dot0_rad_s)


def rules_json() -> dict[str, dict[str, Any]]:
    """The check's fixed rules, each as ``{"value", "why"}`` (a report's ``policy``)."""
    return {
        "split_share": {"value": SPLIT_SHARE, "why": "a decay's model is refitted on its "
                        "swings above this share of the largest and on the rest"},
        "false_alarm": {"value": FALSE_ALARM, "why": "two-sided, divided among the "
                        "parameters compared: a parameter differing between the parts"},
    }


@dataclass(frozen=True)
class Comparison:
    """One parameter fitted on the early and the late part: values, standard errors on the
    fit's scale, and z."""

    name: str
    early: float
    late: float
    z: float


def constancy_finding(data: FitData, final: FitResult, scale: RecordScale) -> Finding | None:
    """A ``constancy`` finding when the final model's parameters differ between the record's
    large swings and the rest (see the module's docstring); None when they agree, or when
    either part lasts less than MIN_SWINGS periods."""
    _, sim = predict(data, final.model, final.values)
    theta = np.asarray(sim.theta, dtype=float)[:data.t.size]
    if theta.size < data.t.size:
        return None
    ahead = np.maximum.accumulate(np.abs(theta)[::-1])[::-1]  # the true angle: 0 at rest
    split = int(np.argmax(ahead < SPLIT_SHARE * ahead[0]))
    period = 2.0 * math.pi / final.values[q.omega_rad_s]
    if split == 0 or min(data.t[split], data.t[-1] - data.t[split]) < MIN_SWINGS * period:
        return None
    early_data = replace(data, t=data.t[:split], y=data.y[:split], valid=data.valid[:split])
    late_data = replace(data, t=data.t[split:] - data.t[split], y=data.y[split:],
                       valid=data.valid[split:])
    early = fit(early_data, final.model, final.values, scale)
    late = fit(late_data, final.model, {**final.values, q.theta0_rad: float(sim.theta[split]),
                                        q.theta_dot0_rad_s: float(sim.theta_dot[split])},
               scale)
    compared = _compared(data, final, scale, early, late)
    if not compared:
        return None
    needed = float(stats.norm.isf(FALSE_ALARM / (2.0 * len(compared))))
    worst = max(compared, key=lambda c: abs(c.z))
    if abs(worst.z) < needed:
        return None
    differing = sorted((c for c in compared if abs(c.z) >= needed), key=lambda c: -abs(c.z))
    listed = "; ".join(f"{c.name} {c.early:.4g} against {c.late:.4g} (z {c.z:.3g})"
                       for c in differing)
    sentence = (f"the model's parameters differ between the swings above "
                f"{100 * SPLIT_SHARE:g} % of the largest (to {data.t[split]:.3g} s) and the "
                f"rest: {listed}; a term whose effect changes with the swing's size is missing")
    numbers = {"split_s": float(data.t[split]), "z_needed": needed,
               **{f"z_{c.name}": c.z for c in compared}}
    return Finding("constancy", sentence, numbers)


def _compared(data: FitData, final: FitResult, scale: RecordScale, early: FitResult,
              late: FitResult) -> list[Comparison]:
    """The parameters both parts determine, off their bounds, with their z."""
    out = []
    for name, (_, plan, lower, upper) in free_parameters(data, final.model, scale,
                                                         final.values).items():
        if name in STATES:
            continue
        a, b = early.estimates.get(name), late.estimates.get(name)
        if a is None or b is None or a.ci95 is None or b.ci95 is None:
            continue
        if any(_on_bound(x.value, lower, upper) for x in (a, b)):
            continue
        if plan.log:
            values = math.log(a.value), math.log(b.value)
            errors = [math.log(x.ci95[1] / x.ci95[0]) / (2.0 * Z95) for x in (a, b)]
        else:
            values = a.value, b.value
            errors = [(x.ci95[1] - x.ci95[0]) / (2.0 * Z95) for x in (a, b)]
        spread = math.hypot(*errors)
        if not spread > 0:
            continue
        out.append(Comparison(name, a.value, b.value, (values[0] - values[1]) / spread))
    return out


def _on_bound(value: float, lower: float, upper: float) -> bool:
    """Whether a fitted value sits on a bound of its range (its interval means nothing)."""
    return any(math.isfinite(bound) and abs(value - bound) <= 1e-9 * max(1.0, abs(bound))
               for bound in (lower, upper))
