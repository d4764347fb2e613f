"""Which file becomes which :class:`~analysis.records.Record`: a plain table of loaders by suffix.

The exchange CSV + JSON (docs/MODEL.md section 5) and the recorder's HDF5 files
(docs/recording_layout.md) are read into the same ``Record``, so every analysis works
unchanged on either source.  This module sits above both readers and imports them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from analysis.exchange import read_exchange, read_meta, sidecar_path
from analysis.hdf5_records import load_hdf5_record
from analysis.output_paths import HDF5_SUFFIXES
from analysis.records import Record
from recording.errors import RecordFormatError
from recording.reader import open_recording


def load_exchange_record(path: Path, meta_path: Path | None = None) -> Record:
    """An exchange CSV (its JSON sidecar beside it, or ``meta_path``) as a record."""
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
        # what the sidecar says beyond the model's needs; who wrote it describes that file
        context={k: v for k, v in meta.extra.items() if k not in ("source", "provenance")},
    )


Loader = Callable[[Path, Path | None], Record]

LOADERS: dict[str, Loader] = {
    ".csv": load_exchange_record,
    ".h5": load_hdf5_record,
    ".hdf5": load_hdf5_record,
}


def load_record(path: str | Path, meta_path: str | Path | None = None) -> Record:
    """Read a record with the loader of its suffix (a CSV's sidecar beside it, or ``meta_path``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    loader = LOADERS.get(suffix)
    if loader is None:
        raise RecordFormatError(
            f"{path}: unknown file type {suffix or '(none)'!r}; expected one of {sorted(LOADERS)}"
        )
    return loader(path, Path(meta_path) if meta_path else None)


def is_sweep(paths: Sequence[str | Path], meta_path: str | Path | None = None) -> bool:
    """Whether ``paths`` are a sweep: several files, or one recording or exported CSV that
    lists sweep steps.  (A file that cannot be read is no sweep here: its loader says why.)
    Here, beside the loaders, so that a command asks it before importing any analysis; a
    recording's step table alone is read (its loader reads and verifies the samples)."""
    if len(paths) > 1:
        return True
    path = Path(paths[0])
    try:
        if path.suffix.lower() in HDF5_SUFFIXES:
            with open_recording(path) as recording:
                return bool(recording.sweep_steps().size)
        if path.suffix.lower() == ".csv":
            return bool(read_meta(meta_path or sidecar_path(path)).extra.get("sweep_steps"))
    except (OSError, ValueError, KeyError):
        return False
    return False
