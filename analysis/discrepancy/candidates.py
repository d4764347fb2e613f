"""Which named causes are candidates on a record, and how a fit of each one starts.

The fitter is one general mechanism over the registry ``analysis.extensions.CAUSES``;
a cause can show in a kind of experiment when the kind provides what the cause needs
(:mod:`analysis.experiments`).  How a fit of a cause starts (each parameter's start value
and finite-difference step, scaled to the record at hand) and which baseline parameters
its own take over are the cause's declarations (``Cause.plan``, ``Cause.replaces``).
"""

from __future__ import annotations

from analysis.experiments import experiment_kind
from analysis.extensions import CAUSES, Cause, ParameterPlan, RecordScale


def plan_for(cause: Cause, scale: RecordScale) -> dict[str, ParameterPlan]:
    """Start values and steps of a cause's parameters; a cause without a declared plan
    starts at its registry defaults with steps of 1e-6 of its parameter range."""
    if cause.plan is not None:
        return dict(cause.plan(scale))
    return {
        spec.name: ParameterPlan(spec.default, 1e-6 * (spec.upper - spec.lower))
        for spec in cause.parameters
    }


def candidates_for(experiment: str) -> list[Cause]:
    """The registered causes that can show in a record of ``experiment``."""
    kind = experiment_kind(experiment)
    return [c for c in CAUSES.values() if kind.hidden_reason(c.needs) is None]


def excluded_for(experiment: str) -> dict[str, str]:
    """Causes that cannot show in a record of ``experiment``, each with the reason."""
    kind = experiment_kind(experiment)
    out = {}
    for c in CAUSES.values():
        reason = kind.hidden_reason(c.needs)
        if reason is not None:
            out[c.name] = reason
    return out
