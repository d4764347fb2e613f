"""A :class:`~analysis.sweep.steps.Sweep` from the files a lab has of one.

Three sources give the same value:

- an HDF5 recording with a ``/sweep_steps`` table (docs/recording_layout.md), each step
  its dwell with the step's setting;
- a sweep exported as one CSV (``impact-rig export`` without ``--per-step``), whose JSON
  sidecar lists the steps under ``sweep_steps``;
- several files given together, in running order as given: per-step files
  (``impact-rig export --per-step``, or one record per setting taken by hand), and sweeps
  among them, each giving its steps (a forced record and the recording of the steps that
  ``impact-rig suggest`` planned for it, analysed as one rig).

A step that cannot be judged is set aside with the reason, not fatal: one the sweep was
interrupted in (``complete`` 0; an interrupted sweep is analysed up to its last complete
step), one whose dwell is shorter than :data:`MIN_DWELL_S`, one with lost samples in its
dwell.  A file that is no sweep at all is refused with one line naming the step and what
is wrong: no steps, steps that overlap, a step without tach edges (its drive's phase is
unknown), a setting no drive has.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from analysis import quantities as q
from analysis.exchange import sidecar_path
from analysis.hdf5_records import read_recording_arrays, stretch_record
from analysis.identify.forced import MIN_DURATION_S
from analysis.output_paths import HDF5_SUFFIXES
from analysis.record_loaders import is_sweep, load_record
from analysis.records import Record
from analysis.sweep.steps import UNKNOWN, SetAside, Sweep, SweepStep, SweptParameter
from recording.errors import RecordFormatError

MIN_DWELL_S = MIN_DURATION_S  # a forced record's least duration: tens of drive periods


class SweepFormatError(RecordFormatError):
    """A file (or files) that is no sweep: no steps, overlapping steps, a step without tach."""


def load_sweep(paths: Sequence[str | Path], meta_path: str | Path | None = None) -> Sweep:
    """The sweep in ``paths``: one recording or exported sweep CSV, or several per-step
    files (see the module's docstring)."""
    if not paths:
        raise SweepFormatError("no file given")
    if len(paths) > 1:
        if meta_path is not None:
            raise SweepFormatError(f"{meta_path}: --meta names one file's sidecar; per-step "
                                   "files each carry their own")
        return sweep_from_step_files(paths)
    path = Path(paths[0])
    if path.suffix.lower() in HDF5_SUFFIXES:
        return sweep_from_recording(path)
    return sweep_from_exchange(path, meta_path)


def sweep_from_recording(path: str | Path) -> Sweep:
    """The steps of an HDF5 recording's ``/sweep_steps``, each its dwell with its setting."""
    path = Path(path)
    arrays = read_recording_arrays(path)
    rows = arrays.steps
    if not rows.size:
        raise SweepFormatError(f"{path}: no sweep steps (/sweep_steps is empty); a single "
                               "forced record is analysed without them")
    _check_order(path, [(int(r["step"]), int(r["settle_start_index"]),
                         int(r["dwell_start_index"]), int(r["dwell_end_index"]))
                        for r in rows],
                 interrupted={int(r["step"]) for r in rows if not r["complete"]})
    rate = _rate(arrays.indices, arrays.time_s)
    steps, aside = [], []
    for row in rows:
        number = int(row["step"])
        if not row["complete"]:
            aside.append(SetAside(number, "interrupted: the sweep stopped during this step"))
            continue
        first, end = int(row["dwell_start_index"]), int(row["dwell_end_index"])
        positions = np.flatnonzero((arrays.indices >= first) & (arrays.indices < end))
        if positions.size < end - first:
            aside.append(SetAside(number, f"lost samples: {end - first - positions.size} of "
                                  f"its dwell's {end - first} never arrived"))
            continue
        dwell_s = (end - first) / rate
        if dwell_s < MIN_DWELL_S:
            aside.append(_too_short(number, dwell_s))
            continue
        drive = {q.frequency_hz: float(row[q.frequency_hz]),
                 q.amplitude_m: float(row[q.amplitude_m])}
        record = stretch_record(arrays, positions, path, f" step {number}", drive)
        steps.append(_step(path, number, int(row["direction"]), drive,
                           (first - int(row["settle_start_index"])) / rate, record))
    return _sweep(path, steps, aside)


def sweep_from_exchange(path: str | Path, meta_path: str | Path | None = None) -> Sweep:
    """The steps of a sweep exported as one CSV: the sidecar's ``sweep_steps`` (times in
    the CSV's own clock) cut the record into dwells."""
    path = Path(path)
    whole = load_record(path, meta_path)
    listed = whole.context.get("sweep_steps")
    if not listed:
        raise SweepFormatError(f"{meta_path or sidecar_path(path)}: no sweep_steps; one "
                               "forced record is analysed without them")
    try:
        spans = [(int(s["step"]), float(s["start_s"]), float(s["dwell_start_s"]),
                  float(s["dwell_end_s"])) for s in listed]
    except (KeyError, TypeError, ValueError) as error:
        raise SweepFormatError(f"{meta_path or sidecar_path(path)}: sweep_steps: each step "
                               "needs step, start_s, dwell_start_s, dwell_end_s "
                               f"({error!r})") from None
    _check_order(path, spans, interrupted={number for (number, *_), entry
                                           in zip(spans, listed, strict=True)
                                           if not entry.get("complete", True)})
    t = whole.time_s
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    steps, aside = [], []
    for entry, (number, start_s, first_s, end_s) in zip(listed, spans, strict=True):
        if not entry.get("complete", True):
            aside.append(SetAside(number, "interrupted: the sweep stopped during this step"))
            continue
        select = np.flatnonzero((t >= first_s - 0.5 * dt) & (t < end_s - 0.5 * dt))
        if select.size * dt < end_s - first_s - 1.5 * dt:
            aside.append(SetAside(number, f"lost samples: the file holds "
                                  f"{select.size * dt:.3g} s of its {end_s - first_s:.3g} s "
                                  "dwell"))
            continue
        if select.size * dt < MIN_DWELL_S:
            aside.append(_too_short(number, select.size * dt))
            continue
        drive = {q.frequency_hz: _number(path, number, entry, q.frequency_hz),
                 q.amplitude_m: _number(path, number, entry, q.amplitude_m)}
        record = _dwell(whole, select, f" step {number}", drive)
        steps.append(_step(path, number, int(entry.get("direction", UNKNOWN)), drive,
                           first_s - start_s, record))
    return _sweep(path, steps, aside)


def sweep_from_step_files(paths: Sequence[str | Path]) -> Sweep:
    """One step per file, in the order given (their settle unknown, taken as 0); a file that
    is a sweep itself (a recording with sweep steps, such as ``impact-rig sweep --plan``
    writes, or an exported sweep CSV) gives its steps, with their settles, in its place.
    The steps are numbered in running order over all the files."""
    steps, aside = [], []
    number = 0
    for path in paths:
        if is_sweep([path]):
            inner = load_sweep([path])
            last = max([s.number for s in inner.steps] + [s.number for s in inner.set_aside])
            steps += [replace(s, number=number + s.number) for s in inner.steps]
            aside += [SetAside(number + s.number, f"{s.reason} ({path})")
                      for s in inner.set_aside]
            number += last + 1
            continue
        record = load_record(path)
        if not record.kind.driven:
            raise SweepFormatError(f"{path}: a {record.experiment} record; every file of a "
                                   "sweep is a forced record")
        dwell_s = float(record.time_s[-1] - record.time_s[0]) if record.time_s.size else 0.0
        if dwell_s < MIN_DWELL_S:
            aside.append(_too_short(number, dwell_s, f" ({path})"))
        else:
            drive = dict(record.drive or {})
            for key in (q.frequency_hz, q.amplitude_m):
                drive[key] = _number(path, number, drive, key)
            steps.append(_step(Path(path), number, UNKNOWN, drive, 0.0, record))
        number += 1
    source = ", ".join(str(p) for p in paths)
    return _sweep(source, steps, aside)


def _check_order(path: str | Path, spans: list[tuple[int, int | float, int | float,
                                                     int | float]],
                 interrupted: set[int] | frozenset[int] = frozenset()) -> None:
    """Steps in running order, each settle before its dwell, none overlapping the next;
    a step in ``interrupted`` may end before its dwell began (stopped while settling)."""
    previous = None
    for number, start, first, end in spans:
        if not (start <= first < end or (number in interrupted and start <= first <= end)):
            raise SweepFormatError(f"{path}: sweep step {number}: its settle starts at "
                                   f"{start}, its dwell at {first} and ends at {end}; "
                                   "expected settle <= dwell start < dwell end")
        if previous is not None:
            before, before_end = previous
            if number <= before:
                raise SweepFormatError(f"{path}: sweep step {number} follows step {before}; "
                                       "steps must be numbered in running order")
            if start < before_end:
                raise SweepFormatError(f"{path}: sweep step {number} overlaps step {before}: "
                                       f"it starts at {start}, before step {before}'s dwell "
                                       f"ends at {before_end}")
        previous = (number, end)


def _step(path: str | Path, number: int, direction: int, drive: Mapping[str, float],
          settle_s: float, record: Record) -> SweepStep:
    """A step, refused when its dwell has no tach edge or its setting no drive."""
    if record.tach_indices.size == 0:
        raise SweepFormatError(f"{path}: sweep step {number}: no tach edges in its dwell; "
                               "the drive's phase cannot be measured")
    try:
        return SweepStep(number, direction, drive[q.frequency_hz], drive[q.amplitude_m],
                         settle_s, record)
    except ValueError as error:
        raise SweepFormatError(f"{path}: {error}") from None


def _sweep(source: str | Path, steps: list[SweepStep], aside: list[SetAside]) -> Sweep:
    """The sweep of ``steps``, or an error naming why no step is left to analyse; an
    interrupted sweep keeps its complete steps up to the interruption."""
    if not steps:
        reasons = "; ".join(f"step {s.number}: {s.reason}" for s in aside)
        raise SweepFormatError(f"{source}: no step to analyse" + (f" ({reasons})" if reasons
                                                                  else ""))
    return Sweep(str(source), swept_parameter(steps), tuple(steps), tuple(aside))


def swept_parameter(steps: Sequence[SweepStep]) -> SweptParameter:
    """What the sweep stepped: the frequency when it changes over the steps, else the
    amplitude."""
    if len({round(s.frequency_hz, 9) for s in steps}) > 1:
        return "frequency"
    return "amplitude"


def _dwell(whole: Record, select: np.ndarray, label: str, drive: Mapping[str, float]) -> Record:
    """Samples ``select`` (a contiguous run) of ``whole`` as a record with ``drive``."""
    first, stop = int(select[0]), int(select[-1]) + 1
    tach = whole.tach_indices[(whole.tach_indices >= first) & (whole.tach_indices < stop)]
    context: dict[str, Any] = {k: v for k, v in whole.context.items() if k != "sweep_steps"}
    return Record(
        time_s=whole.time_s[first:stop], angle_rad=whole.angle_rad[first:stop],
        experiment=whole.experiment, rig=whole.rig, drive=drive,
        table_m=None if whole.table_m is None else whole.table_m[first:stop],
        tach_indices=tach - first, source=f"{whole.source}{label}", notes=whole.notes,
        context=context,
    )


def _number(path: str | Path, number: int, entry: Mapping[str, Any], key: str) -> float:
    """A step's setting ``key`` as a float, or an error naming the step."""
    try:
        return float(entry[key])
    except (KeyError, TypeError, ValueError):
        raise SweepFormatError(f"{path}: sweep step {number}: no {key} (got "
                               f"{entry.get(key)!r})") from None


def _too_short(number: int, dwell_s: float, where: str = "") -> SetAside:
    return SetAside(number, f"too short to judge: a dwell of {dwell_s:.3g} s{where}, a step "
                    f"needs {MIN_DWELL_S:g} s")


def _rate(indices: np.ndarray, times: np.ndarray) -> float:
    """Samples per second of a recording's angle channel."""
    if indices.size < 2 or times[-1] <= times[0]:
        raise SweepFormatError("the recording holds fewer than two samples")
    return float((indices[-1] - indices[0]) / (times[-1] - times[0]))
