"""The CSV + JSON exchange format of docs/MODEL.md section 5: read it with clear errors, write it.

A record is a uniformly sampled angle (plus optional table displacement and tach
pulses) with a JSON sidecar naming the experiment, the rig constants and the drive.
Files are parsed, never evaluated.
"""

from __future__ import annotations

import csv
import json
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from analysis.experiments import NAMES, experiment_kind
from analysis.json_output import write_json

REQUIRED_COLUMNS = ("time_s", "angle_rad")
OPTIONAL_COLUMNS = ("table_m", "tach")
RIG_KEYS = ("m_kg", "l_m", "R_m", "g")
OPTIONAL_RIG_KEYS = ("L_m",)  # the rig's equivalent length when the lab measured it
# the sidecar's layout; 1 is also what a sidecar without the key is read as
FORMAT_VERSION = 1
# A pendulum that strikes a barrier never passes the top: an angle beyond pi rad is not an
# angle in radians (degrees read as radians, most often)
MAX_ANGLE_RAD = math.pi
UNIFORM_TOLERANCE = 1e-3  # allowed deviation of a time step, as a fraction of the mean step


class ExchangeFormatError(ValueError):
    """A CSV or JSON file does not follow the exchange format; the message names file and field."""


@dataclass(frozen=True)
class ExchangeMeta:
    """The JSON sidecar: experiment kind, rig constants (None where unknown), drive, notes."""

    experiment: str
    rig: dict[str, float | None] = field(default_factory=dict)
    drive: dict[str, float] | None = None
    notes: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def as_json(self) -> dict[str, Any]:
        """The sidecar as a JSON-ready dict (extra keys kept)."""
        out: dict[str, Any] = {"format_version": FORMAT_VERSION,
                               "experiment": self.experiment, "rig": dict(self.rig)}
        if self.drive is not None:
            out["drive"] = dict(self.drive)
        out["notes"] = self.notes
        out.update(self.extra)
        return out


@dataclass(frozen=True)
class ExchangeRecord:
    """One uniformly sampled record: time base, angle and the optional channels."""

    time_s: np.ndarray
    angle_rad: np.ndarray
    meta: ExchangeMeta
    table_m: np.ndarray | None = None
    tach: np.ndarray | None = None

    @property
    def sample_rate_hz(self) -> float:
        """Sampling rate from the mean time step."""
        return (self.time_s.size - 1) / (self.time_s[-1] - self.time_s[0])

    @property
    def tach_indices(self) -> np.ndarray:
        """Sample indices of the tach pulses (empty when there is no tach column)."""
        if self.tach is None:
            return np.zeros(0, dtype=np.int64)
        return np.flatnonzero(self.tach > 0.5)


def rig_constants(rig: Mapping[str, Any]) -> dict[str, Any]:
    """The sidecar's rig constants from a fuller mapping (a recording's rig, a record's): every
    exchange key (None where unknown) and the optional ones that are known."""
    return {key: rig.get(key) for key in RIG_KEYS} | {
        key: rig[key] for key in OPTIONAL_RIG_KEYS if rig.get(key)}


def sidecar_path(csv_path: str | Path) -> Path:
    """NAME.json beside NAME.csv."""
    return Path(csv_path).with_suffix(".json")


def read_meta(path: str | Path) -> ExchangeMeta:
    """Parse and validate a JSON sidecar."""
    path = Path(path)
    try:
        raw = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ExchangeFormatError(
            f"{path}: metadata file not found (put NAME.json beside NAME.csv or pass --meta)"
        ) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise ExchangeFormatError(f"{path}: not valid JSON ({error})") from None
    return meta_from_json(raw, path)


def meta_from_json(raw: Any, path: str | Path) -> ExchangeMeta:
    """Validate already parsed sidecar JSON (``path`` names its source in errors).

    Simulated HDF5 files carry the same JSON as an attribute, so the check lives apart
    from the file reading.
    """
    path = Path(path)
    if not isinstance(raw, dict):
        raise ExchangeFormatError(f"{path}: expected a JSON object at the top level")
    version = raw.get("format_version", 1)
    if isinstance(version, bool) or version not in range(1, FORMAT_VERSION + 1):
        raise ExchangeFormatError(
            f"{path}: 'format_version' is {version!r}; this impact-rig reads versions 1 to "
            f"{FORMAT_VERSION} (a newer one was written by a newer impact-rig: update it)"
        )
    experiment = raw.get("experiment")
    if experiment not in NAMES:
        raise ExchangeFormatError(
            f"{path}: 'experiment' is {experiment!r}; expected one of {', '.join(NAMES)}"
        )
    rig_raw = raw.get("rig") or {}
    if not isinstance(rig_raw, dict):
        raise ExchangeFormatError(f"{path}: 'rig' must be an object with keys {RIG_KEYS}")
    rig = {key: _optional_positive(path, f"rig.{key}", rig_raw.get(key)) for key in RIG_KEYS}
    rig |= {key: _optional_positive(path, f"rig.{key}", rig_raw[key])
            for key in OPTIONAL_RIG_KEYS if key in rig_raw}
    drive = raw.get("drive")
    if drive is not None:
        if not isinstance(drive, dict):
            raise ExchangeFormatError(f"{path}: 'drive' must be an object")
        drive = {
            key: _optional_positive(path, f"drive.{key}", value, allow_zero=True)
            for key, value in drive.items()
        }
    if experiment_kind(experiment).driven:
        for key in ("frequency_hz",):
            if not drive or drive.get(key) is None:
                whole_sweep = " (this is a whole sweep whose drive changes step by step: " \
                    "export it with --per-step to analyse one step)" \
                    if raw.get("sweep_steps") else ""
                raise ExchangeFormatError(
                    f"{path}: a forced record needs 'drive.{key}' (the drive frequency)"
                    + whole_sweep
                )
    notes = raw.get("notes") or ""
    if not isinstance(notes, str):
        raise ExchangeFormatError(f"{path}: 'notes' must be a string")
    extra = {k: v for k, v in raw.items()
             if k not in ("format_version", "experiment", "rig", "drive", "notes")}
    return ExchangeMeta(experiment, rig, drive, notes, extra)


def _optional_positive(
    path: Path, key: str, value: Any, *, allow_zero: bool = False
) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ExchangeFormatError(f"{path}: '{key}' is {value!r}; expected a number or null")
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise ExchangeFormatError(f"{path}: '{key}' is {value!r}; expected a positive number")
    return float(value)


def read_exchange(csv_path: str | Path, meta_path: str | Path | None = None) -> ExchangeRecord:
    """Read NAME.csv and its sidecar (NAME.json, or ``meta_path``), validating both."""
    csv_path = Path(csv_path)
    if not csv_path.is_file():  # name the missing data file, not its missing sidecar
        raise ExchangeFormatError(f"{csv_path}: file not found")
    meta = read_meta(meta_path or sidecar_path(csv_path))
    columns = _read_columns(csv_path)
    time_s = columns["time_s"]
    if time_s.size < 2:
        raise ExchangeFormatError(f"{csv_path}: needs at least 2 samples, found {time_s.size}")
    if not np.all(np.isfinite(time_s)):
        row = int(np.flatnonzero(~np.isfinite(time_s))[0]) + 2
        raise ExchangeFormatError(f"{csv_path}: line {row}: time_s is not a finite number")
    steps = np.diff(time_s)
    # the sampling step is the median one: a single jump moves the mean step off every other
    # step, and the first step would be blamed instead of the jump
    step = float(np.median(steps))
    if step <= 0:
        raise ExchangeFormatError(f"{csv_path}: time_s must increase")
    bad = np.flatnonzero(np.abs(steps - step) > UNIFORM_TOLERANCE * step + 1e-9)
    if bad.size:
        first = int(bad[0])  # time_s[first + 1], on line first + 3, is off the grid
        raise ExchangeFormatError(
            f"{csv_path}: line {first + 3}: time_s jumps from {time_s[first]:.9g} to "
            f"{time_s[first + 1]:.9g} s (a step of {steps[first]:.6g} s; the record's is "
            f"{step:.6g} s); the exchange format needs uniform sampling"
        )
    for name in ("angle_rad", "table_m"):
        values = columns.get(name)
        if values is not None and not np.all(np.isfinite(values)):
            row = int(np.flatnonzero(~np.isfinite(values))[0]) + 2
            raise ExchangeFormatError(
                f"{csv_path}: line {row}: {name} is {float(values[row - 2])}, not a finite number; "
                "remove the row or mark the sample some other way (a gap is not allowed here)"
            )
    _check_angle_range(csv_path, columns["angle_rad"])
    return ExchangeRecord(
        time_s=time_s,
        angle_rad=columns["angle_rad"],
        meta=meta,
        table_m=columns.get("table_m"),
        tach=columns.get("tach"),
    )


def _check_angle_range(path: Path, angle_rad: np.ndarray) -> None:
    """An angle no pendulum on this rig can reach is refused, asking whether it is in degrees."""
    largest = int(np.argmax(np.abs(angle_rad)))
    value = float(angle_rad[largest])
    if abs(value) <= MAX_ANGLE_RAD:
        return
    swing = float(np.max(angle_rad) - np.min(angle_rad))
    hint = (
        f"is the column in degrees? ({value:.6g} degrees would be "
        f"{math.radians(value):.6g} rad; convert it with radians())"
        if abs(value) <= 360
        else "the column does not hold angles in radians"
    )
    raise ExchangeFormatError(
        f"{path}: line {largest + 2}: angle_rad is {value:.6g} (a swing of {swing:.6g}); a "
        f"pendulum that strikes a barrier never passes {MAX_ANGLE_RAD:.4f} rad: {hint}"
    )


def _check_utf8(path: Path) -> None:
    """The exchange CSV is UTF-8: name the first line that is not, and the byte."""
    with path.open("rb") as handle:
        for number, line in enumerate(handle, start=1):
            try:
                line.decode("utf-8")
            except UnicodeDecodeError as error:
                raise ExchangeFormatError(
                    f"{path}: line {number}: byte 0x{line[error.start]:02X} is not UTF-8 text; "
                    "the exchange CSV is UTF-8 (saved as Latin-1 or Windows-1252? save it "
                    "again as UTF-8)"
                ) from None


def _read_columns(path: Path) -> dict[str, np.ndarray]:
    try:
        _check_utf8(path)
    except FileNotFoundError:
        raise ExchangeFormatError(f"{path}: file not found") from None
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            header = next(csv.reader(handle), None)
    except FileNotFoundError:
        raise ExchangeFormatError(f"{path}: file not found") from None
    except UnicodeDecodeError:
        raise ExchangeFormatError(f"{path}: not a text CSV file") from None
    if not header:
        raise ExchangeFormatError(f"{path}: empty file; expected a header row")
    header = [name.strip() for name in header]
    missing = [name for name in REQUIRED_COLUMNS if name not in header]
    if missing:
        raise ExchangeFormatError(f"{path}: missing column(s) {missing}; the header has {header}")
    wanted = [name for name in REQUIRED_COLUMNS + OPTIONAL_COLUMNS if name in header]
    usecols = [header.index(name) for name in wanted]
    try:
        with warnings.catch_warnings():  # no rows is this format's error below, not numpy's
            warnings.filterwarnings("ignore", "loadtxt: input contained no data", UserWarning)
            data = np.loadtxt(
                path,
                delimiter=",",
                skiprows=1,
                usecols=usecols,
                ndmin=2,
                dtype=float,
                encoding="utf-8",
            )
    except ValueError as error:
        raise ExchangeFormatError(f"{path}: {_first_bad_line(path, usecols) or error}") from None
    if data.shape[0] == 0:
        raise ExchangeFormatError(f"{path}: no data rows after the header")
    return {name: data[:, i].copy() for i, name in enumerate(wanted)}


def _first_bad_line(path: Path, usecols: list[int]) -> str | None:
    with path.open(newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        for line_number, row in enumerate(reader, start=2):
            for col in usecols:
                try:
                    float(row[col])
                except (IndexError, ValueError):
                    value = row[col] if col < len(row) else "<missing>"
                    return f"line {line_number}: column {header[col].strip()!r} is {value!r}"
    return None


def _column_text(values: np.ndarray, fmt: str) -> np.ndarray:
    """A column as text: float32 samples (as a recording holds them) in the shortest text
    that reads back the same float32, anything else in ``fmt``."""
    values = np.asarray(values)
    if values.dtype == np.float32:
        return np.array([np.format_float_positional(v, unique=True, trim="-") if
                         1e-4 <= abs(v) < 1e7 or v == 0 else
                         np.format_float_scientific(v, unique=True, trim="-") for v in values])
    return np.char.mod(fmt, np.asarray(values, dtype=float))


def write_exchange(
    csv_path: str | Path, record: ExchangeRecord, *, overwrite: bool = False
) -> tuple[Path, Path]:
    """Write NAME.csv and NAME.json; returns both paths.  An existing file is refused
    (FileExistsError) unless ``overwrite``."""
    csv_path = Path(csv_path)
    names = ["time_s", "angle_rad"]
    columns = [_column_text(record.time_s, "%.12g"), _column_text(record.angle_rad, "%.12g")]
    if record.table_m is not None:
        names.append("table_m")
        columns.append(_column_text(record.table_m, "%.9g"))
    if record.tach is not None:
        names.append("tach")
        columns.append(np.char.mod("%d", np.asarray(record.tach, dtype=np.int64)))
    with csv_path.open("w" if overwrite else "x", encoding="utf-8") as handle:
        handle.write(",".join(names) + "\n")
        handle.writelines(",".join(row) + "\n" for row in zip(*columns, strict=True))
    json_path = write_json(sidecar_path(csv_path), record.meta.as_json(), overwrite=overwrite)
    return csv_path, json_path
