"""Bifurcation diagrams kept in files, to draw over a computed one: a recorded sweep.

A file is recognised by its root ``format`` attribute; each kind becomes
:class:`BifurcationDiagram` objects over a named model parameter, so whatever draws them
(the continuation's figure) needs no knowledge of the file.  A recorded sweep
(``impact-rig sweep``, docs/recording_layout.md) gives one diagram per direction: each
complete step's dwell strobed at drive phase 0 on its tach (on the stated drive without
one), at the step's beta = A / L (L from the recording's rig) or drive frequency.
Another kind of file joins by adding its ``format`` and a reader to ``READERS``.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np

from analysis import quantities as q
from analysis.dynamics.bifurcation import BifurcationDiagram, bifurcation_from_recording
from analysis.dynamics.strobe import strobe_record
from analysis.hdf5_records import load_hdf5_steps, read_recording_arrays
from recording.layout import FORMAT_NAME

SWEPT = (q.beta, q.f_drive_hz)  # what a recorded sweep can be drawn over


class DiagramFileError(ValueError):
    """A file that holds no diagram over the wanted parameter; the message says why."""


def recorded_sweep_diagrams(path: str | Path, parameter: str = q.beta
                            ) -> tuple[BifurcationDiagram, ...]:
    """The Poincare points of a recorded sweep's complete steps, one diagram per direction
    that occurs ('recorded up', 'recorded down'), over ``parameter`` (beta or f_drive_hz)."""
    if parameter not in SWEPT:
        raise DiagramFileError(f"{path}: a recorded sweep is drawn over {' or '.join(SWEPT)}, "
                               f"not {parameter!r}")
    records = load_hdf5_steps(path)
    steps = read_recording_arrays(path).steps
    directions = steps["direction"][steps["complete"] == 1]
    values, sections = [], []
    for record in records:
        drive = record.drive
        if parameter == q.beta:
            values.append(drive[q.amplitude_m] / record.rig_parameters().L_m)
        else:
            values.append(drive[q.frequency_hz])
        strobe = strobe_record(record.angle_rad, record.sample_rate_hz,
                               tach_indices=record.tach_indices,
                               frequency_hz=drive[q.frequency_hz])
        sections.append(strobe.section)
    values = np.array(values)
    diagrams = []
    for sign, name in ((1, "recorded up"), (-1, "recorded down")):
        chosen = np.flatnonzero(directions == sign)
        if chosen.size:
            diagram = bifurcation_from_recording(values[chosen], [sections[i] for i in chosen],
                                                 parameter_name=parameter)
            diagrams.append(BifurcationDiagram(diagram.parameter, diagram.theta,
                                               diagram.theta_dot, name, parameter))
    return tuple(diagrams)


Reader = Callable[[Path, str], tuple[BifurcationDiagram, ...]]
READERS: dict[str, Reader] = {FORMAT_NAME: recorded_sweep_diagrams}


def read_diagrams(path: str | Path, parameter: str) -> tuple[BifurcationDiagram, ...]:
    """The diagrams a file holds over ``parameter``, by the file's ``format``."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as handle:
            kind = handle.attrs.get("format")
    except OSError as error:
        raise DiagramFileError(f"{path}: cannot be read as HDF5 ({error})") from None
    kind = kind.decode() if isinstance(kind, bytes) else kind
    reader = READERS.get(kind)
    if reader is None:
        known = ", ".join(f"{name!r}" for name in READERS)
        raise DiagramFileError(f"{path}: format {kind!r} holds no diagram to draw (known: "
                               f"{known}, e.g. a recording of 'impact-rig sweep')")
    return reader(path, parameter)
