"""Setting and reading one named model parameter: a rig field, the drive's beta, A_m or
f_drive_hz, or a parameter of an active cause (docs/MODEL.md sections 3 and 6)."""

from __future__ import annotations

from dataclasses import fields, replace

from analysis import quantities as q
from analysis.dynamics.sweeps import model_at_beta
from analysis.model import Model, RigParameters
from analysis.packed import ParameterError

DRIVE_PARAMETERS = (q.beta, q.A_m, q.f_drive_hz)
RIG_PARAMETERS = tuple(f.name for f in fields(RigParameters))


def model_with(model: Model, name: str, value: float) -> Model:
    """``model`` with one parameter set: a rig field (docs/MODEL.md section 3 names), the drive's
    ``beta`` (A = beta L), ``A_m`` or ``f_drive_hz``, or a parameter of an active cause.

    Everything else stays as it is: varying ``L_m`` keeps the table amplitude A in metres,
    varying ``f_drive_hz`` keeps A (and so beta)."""
    if name == q.beta:
        return model_at_beta(model, value)
    if name == q.A_m:
        return replace(model, drive=replace(model.drive, amplitude_m=float(value)))
    if name == q.f_drive_hz:
        return replace(model, drive=replace(model.drive, frequency_hz=float(value)))
    if name in RIG_PARAMETERS:
        return replace(model, rig=model.rig.with_values(**{name: float(value)}))
    for cause, values in model.extensions.items():
        if name in values:
            return model.with_extension(cause, **{**values, name: float(value)})
    raise ParameterError(f"unknown parameter {name!r}; known: {', '.join(parameter_names(model))}")


def parameter_value(model: Model, name: str) -> float:
    """The current value of a parameter :func:`model_with` knows."""
    if name == q.beta:
        return model.drive.amplitude_m / model.rig.L_m
    if name == q.A_m:
        return model.drive.amplitude_m
    if name == q.f_drive_hz:
        return model.drive.frequency_hz
    if name in RIG_PARAMETERS:
        return float(getattr(model.rig, name))
    for values in model.extensions.values():
        if name in values:
            return float(values[name])
    raise ParameterError(f"unknown parameter {name!r}; known: {', '.join(parameter_names(model))}")


def parameter_names(model: Model) -> list[str]:
    """Every parameter that can be varied in ``model``."""
    causes = [name for values in model.extensions.values() for name in values]
    return [*DRIVE_PARAMETERS, *RIG_PARAMETERS, *causes]
