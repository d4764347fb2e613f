"""A measured record as the analysis sees it, and the loaders that produce it from files.

Identification and discrepancy analysis take a :class:`Record`, never a file: the
exchange CSV + JSON loader lives here, and the recorder's HDF5 loader plugs in
through :func:`register_loader` with the same object, so every analysis works
unchanged on either source.
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from analysis.exchange import read_exchange
from analysis.experiments import NAMES, ExperimentKind, experiment_kind
from analysis.model import G_STANDARD, Drive, RigParameters


class RecordFormatError(ValueError):
    """A file cannot be turned into a record; the message names the file and what was wrong."""


@dataclass(frozen=True)
class Record:
    """One uniformly sampled measurement: angle (rad, docs/MODEL.md convention) and its context.

    ``rig`` holds the known rig constants under the exchange keys ``m_kg``, ``l_m``,
    ``R_m``, ``g`` (None where unknown); ``drive`` the stated ``frequency_hz`` and
    ``amplitude_m`` of a forced run (None when undriven).
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
        known = {"m_kg": "m_kg", "l_m": "l_m", "R_m": "R_m", "g": "g_m_s2"}
        given = {known[k]: float(v) for k, v in self.rig.items() if k in known and v}
        given.update(values)
        return RigParameters().with_values(**given)

    def model_drive(self) -> Drive:
        """The stated drive as a model ``Drive`` (no motion when undriven or unknown)."""
        if not self.drive:
            return Drive()
        return Drive(
            amplitude_m=float(self.drive.get("amplitude_m") or 0.0),
            frequency_hz=float(self.drive.get("frequency_hz") or 0.0),
        )


Loader = Callable[[Path, Path | None], Record]
_LOADERS: dict[str, Loader] = {}


def register_loader(suffix: str, loader: Loader) -> None:
    """Make :func:`load_record` read files ending in ``suffix`` (e.g. ``.h5``) with ``loader``."""
    _LOADERS[suffix.lower()] = loader


def load_record(path: str | Path, meta_path: str | Path | None = None) -> Record:
    """Read a record: exchange CSV (sidecar beside it, or ``meta_path``) or a registered type."""
    path = Path(path)
    suffix = path.suffix.lower()
    loader = _LOADERS.get(suffix)
    if loader is None and suffix in (".h5", ".hdf5"):
        # The recorder's layout is read by analysis.hdf5_records, which registers itself.
        with contextlib.suppress(ImportError):
            importlib.import_module("analysis.hdf5_records")
        loader = _LOADERS.get(suffix)
    if loader is None:
        if suffix in (".h5", ".hdf5"):
            raise RecordFormatError(
                f"{path}: reading HDF5 needs h5py, which is not installed; install it, or "
                "export the recording to CSV + JSON ('impact-rig export') and pass the CSV"
            )
        raise RecordFormatError(
            f"{path}: unknown file type {suffix or '(none)'!r}; expected an exchange .csv "
            f"(or one of {sorted(_LOADERS)})"
        )
    return loader(path, Path(meta_path) if meta_path else None)


def _load_exchange(path: Path, meta_path: Path | None) -> Record:
    exchange = read_exchange(path, meta_path)
    meta = exchange.meta
    return Record(
        time_s=exchange.time_s,
        angle_rad=exchange.angle_rad,
        experiment=meta.experiment,
        rig=meta.rig,
        drive=meta.drive,
        table_m=exchange.table_m,
        tach_indices=exchange.tach_indices,
        source=str(path),
        notes=meta.notes,
    )


register_loader(".csv", _load_exchange)
