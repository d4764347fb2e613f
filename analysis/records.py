"""A measured record as the analysis sees it.

Identification and discrepancy analysis take a :class:`Record`, never a file; the
loaders that make one from an exchange CSV or an HDF5 recording are in
:mod:`analysis.record_loaders`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.experiments import NAMES, ExperimentKind, experiment_kind
from analysis.model import G_STANDARD, Drive, RigParameters
from recording.errors import RecordFormatError


@dataclass(frozen=True)
class Record:
    """One uniformly sampled measurement: angle (rad, docs/MODEL.md convention) and its context.

    ``rig`` holds the known rig constants under the exchange keys ``m_kg``, ``l_m``,
    ``R_m``, ``g`` (None where unknown); ``drive`` the stated ``frequency_hz`` and
    ``amplitude_m`` of a forced run (None when undriven).  ``context`` is what the source
    says beyond what the model needs (the calibrations, the recording's format version, a
    whole sweep's steps), carried into what is written from the record.
    """

    time_s: np.ndarray
    angle_rad: np.ndarray
    experiment: str
    rig: Mapping[str, float | None] = field(default_factory=dict)
    drive: Mapping[str, float] | None = None
    table_m: np.ndarray | None = None
    tach_indices: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    source: str = ""
    notes: str = ""
    context: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        time_s = np.asarray(self.time_s, dtype=float)
        angle = np.asarray(self.angle_rad, dtype=float)
        if time_s.ndim != 1 or angle.shape != time_s.shape:
            raise RecordFormatError(
                f"{self.source or 'record'}: time_s and angle_rad must be 1-D of equal length, "
                f"got shapes {time_s.shape} and {angle.shape}"
            )
        if self.experiment not in NAMES:
            raise RecordFormatError(
                f"{self.source or 'record'}: experiment {self.experiment!r}; expected one of "
                f"{', '.join(NAMES)}"
            )
        object.__setattr__(self, "time_s", time_s)
        object.__setattr__(self, "angle_rad", angle)
        object.__setattr__(self, "rig", MappingProxyType(dict(self.rig)))
        object.__setattr__(self, "context", MappingProxyType(dict(self.context)))
        if self.drive is not None:
            object.__setattr__(self, "drive", MappingProxyType(dict(self.drive)))
        if self.table_m is not None:
            object.__setattr__(self, "table_m", np.asarray(self.table_m, dtype=float))
        object.__setattr__(self, "tach_indices", np.asarray(self.tach_indices, dtype=np.int64))

    @property
    def kind(self) -> ExperimentKind:
        """The kind of experiment (its facts: barrier, drive, what it determines)."""
        return experiment_kind(self.experiment)

    @property
    def sample_rate_hz(self) -> float:
        """Sampling rate from the mean time step."""
        return (self.time_s.size - 1) / (self.time_s[-1] - self.time_s[0])

    @property
    def gravity_m_s2(self) -> float:
        """Local g from the rig constants (standard gravity when unknown)."""
        g = self.rig.get("g")
        return float(g) if g else G_STANDARD

    def rig_parameters(self, **values: float) -> RigParameters:
        """The model's rig constants: the paper's defaults, overridden by what the record knows."""
        known = {q.m_kg: q.m_kg, q.l_m: q.l_m, q.R_m: q.R_m, "g": q.g_m_s2}
        given = {known[k]: float(v) for k, v in self.rig.items() if k in known and v}
        given.update(values)
        return RigParameters().with_values(**given)

    def model_drive(self) -> Drive:
        """The stated drive as a model ``Drive`` (no motion when undriven or unknown)."""
        if not self.drive:
            return Drive()
        return Drive(
            amplitude_m=float(self.drive.get(q.amplitude_m) or 0.0),
            frequency_hz=float(self.drive.get(q.frequency_hz) or 0.0),
        )
