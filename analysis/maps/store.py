"""The map file (HDF5): written task by task as tasks finish, so a killed run resumes.

Layout (root attributes ``format`` = "impact-rig map", ``kind``, ``settings`` and
``provenance`` as JSON, ``runs``: the provenance of every run that worked on the file,
``complete``)::

    points/packed (points, P.SIZE), points/<axis> (points,)   one model per point
    axes/<name> (count,)                                       the values of each axis
    trajectories/point, role, initial (T, 2), theta (T, R), theta_dot (T, R),
                 final (T, 2), contacts (T,), status (T,)     one row per trajectory
    tasks/start, stop, chain_first, done                       the batches and which are done
    summary/...                                                written when the map is complete

The file is written in SWMR mode while tasks run (every flush leaves it consistent); a
run killed mid-way leaves a file that the next run of the same command continues.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from analysis.json_output import to_json_text
from analysis.maps.plan import ROLE_NAMES, MapPlan
from analysis.maps.tasks import NOT_RUN, STATUSES, Task, TaskOutput
from recording.superblock import clear_writer_flags

FORMAT = "impact-rig map"
FORMAT_VERSION = 1
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


class MapFileError(ValueError):
    """A map file that cannot be continued or read; the message names it and says why."""


class MapStore:
    """An open map file that tasks are written into."""

    def __init__(self, path: Path, handle: h5py.File) -> None:
        self.path = path
        self._file = handle
        self.done = handle["tasks/done"][...].astype(bool)

    @classmethod
    def create(cls, path: str | Path, plan: MapPlan, provenance: dict[str, Any]) -> MapStore:
        """A new file for ``plan`` (the caller has checked that ``path`` may be written)."""
        path = Path(path)
        handle = h5py.File(path, "w", libver="latest")
        handle.attrs.update(
            format=FORMAT,
            format_version=FORMAT_VERSION,
            kind=plan.kind,
            settings=to_json_text(_settings(plan), one_line=True),
            provenance=to_json_text(provenance, one_line=True),
            runs=to_json_text([provenance], one_line=True),
            complete=False,
        )
        points = handle.create_group("points")
        points["packed"] = plan.packed
        axes = handle.create_group("axes")
        for axis in plan.axes:
            axes[axis.name] = axis.values
        if plan.kind != "basins":
            grids = np.meshgrid(*[axis.values for axis in plan.axes], indexing="ij")
            for axis, grid in zip(plan.axes, grids, strict=True):
                points[axis.name] = grid.ravel()
        t, r = plan.trajectories, plan.settings.record_periods
        rows = max(1, min(plan.batch, t))
        group = handle.create_group("trajectories")
        group["point"] = plan.point
        group["role"] = plan.role
        for name, shape, fill, dtype in (
            ("initial", (t, 2), np.nan, np.float64),
            ("theta", (t, r), np.nan, np.float64),
            ("theta_dot", (t, r), np.nan, np.float64),
            ("final", (t, 2), np.nan, np.float64),
            ("contacts", (t,), 0, np.int64),
            ("status", (t,), NOT_RUN, np.int8),
        ):
            group.create_dataset(
                name, shape, dtype=dtype, fillvalue=fill, chunks=(rows, *shape[1:]),
                compression="gzip", compression_opts=1, shuffle=True,
            )
        group["status"].attrs["names"] = to_json_text(STATUSES, one_line=True)
        group["role"].attrs["names"] = to_json_text(ROLE_NAMES, one_line=True)
        group["initial"][...] = plan.initial
        tasks = handle.create_group("tasks")
        tasks["start"] = [task.start for task in plan.tasks]
        tasks["stop"] = [task.stop for task in plan.tasks]
        tasks["chain_first"] = [task.chain_first for task in plan.tasks]
        tasks.create_dataset("done", (len(plan.tasks),), dtype=np.int8, fillvalue=0)
        handle.swmr_mode = True
        return cls(path, handle)

    @classmethod
    def resume(cls, path: str | Path, plan: MapPlan, provenance: dict[str, Any]) -> MapStore:
        """Continue a file of the same map (MapFileError when it holds another); the run is
        added to the file's ``runs`` unless every task is done already."""
        path = Path(path)
        with path.open("rb") as head:
            if head.read(len(HDF5_SIGNATURE)) != HDF5_SIGNATURE:
                raise MapFileError(
                    f"{path}: exists and is not an HDF5 map file; pass --overwrite to replace "
                    "it, or choose another --out"
                )
        try:
            clear_writer_flags(path)  # a killed writer left them set
            handle = h5py.File(path, "r+", libver="latest")
        except OSError as error:
            raise MapFileError(f"{path}: cannot be opened as a map file ({error})") from None
        try:
            different = _difference(handle, plan)
            if different:
                raise MapFileError(
                    f"{path}: holds a different map ({different}); pass --overwrite to start "
                    "again, or choose another --out"
                )
            if not handle["tasks/done"][...].all():  # a finished file is left as it is
                runs = json.loads(handle.attrs["runs"])
                handle.attrs["runs"] = to_json_text([*runs, provenance], one_line=True)
                handle.swmr_mode = True
        except BaseException:
            handle.close()
            raise
        return cls(path, handle)

    def state_after(self, trajectory: int) -> tuple[np.ndarray, int]:
        """The final state and status code of a trajectory already written."""
        group = self._file["trajectories"]
        return group["final"][trajectory], int(group["status"][trajectory])

    def write(self, task: Task, output: TaskOutput) -> None:
        """Store a finished task and mark it done (data first, so a done task is complete)."""
        rows = slice(task.start, task.stop)
        group = self._file["trajectories"]
        for name in ("initial", "theta", "theta_dot", "final", "contacts", "status"):
            group[name][rows] = getattr(output, name)
        self._file.flush()
        self._file["tasks/done"][task.index] = 1
        self._file.flush()
        self.done[task.index] = True

    def close(self) -> None:
        """Close the file (what was written stays; the map continues on the next run)."""
        self._file.close()


def write_summary(
    path: str | Path, arrays: dict[str, np.ndarray], info: dict[str, Any]
) -> dict[str, Any]:
    """Add the summary of a complete map (group ``summary``, attribute ``summary`` as JSON);
    returns ``info`` as the file holds it (as :func:`read_map` reads it)."""
    text = to_json_text(info, one_line=True)
    with h5py.File(path, "r+", libver="latest") as handle:
        if "summary" in handle:
            del handle["summary"]
        group = handle.create_group("summary")
        for name, values in arrays.items():
            group[name] = values
        handle.attrs["summary"] = text
        handle.attrs["complete"] = True
    return json.loads(text)


def read_map(path: str | Path) -> dict[str, Any]:
    """Everything in a map file as arrays and plain values (MapFileError if it is not one)."""
    path = Path(path)
    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise MapFileError(f"{path}: not a readable HDF5 file ({error})") from None
    with handle:
        if handle.attrs.get("format") != FORMAT:
            raise MapFileError(f"{path}: not an impact-rig map file")
        out: dict[str, Any] = {
            "kind": str(handle.attrs["kind"]),
            "settings": json.loads(handle.attrs["settings"]),
            "provenance": json.loads(handle.attrs["provenance"]),
            "runs": json.loads(handle.attrs["runs"]),
            "complete": bool(handle.attrs["complete"]),
            "summary_info": json.loads(handle.attrs.get("summary", "{}")),
        }
        for group in ("points", "axes", "trajectories", "tasks", "summary"):
            if group in handle:
                out[group] = {name: handle[group][name][...] for name in handle[group]}
        return out


def _settings(plan: MapPlan) -> dict[str, Any]:
    return {
        "kind": plan.kind,
        "axes": [axis.as_dict() for axis in plan.axes],
        **plan.settings.as_dict(),
        "batch": plan.batch,
        "statuses": list(STATUSES),
    }


def _difference(handle: h5py.File, plan: MapPlan) -> str:
    """What differs between the file's map and ``plan`` ('' when they are the same map)."""
    if handle.attrs.get("format") != FORMAT:
        return "not an impact-rig map file"
    stored = json.loads(handle.attrs["settings"])
    for key, value in _settings(plan).items():
        if stored.get(key) != value:
            return f"{key}: {stored.get(key)!r} in the file, {value!r} now"
    if not np.array_equal(handle["points/packed"][...], plan.packed):
        return "the model parameters (--param, --f-drive-hz, --beta ...) differ"
    planned = ~np.isnan(plan.initial[:, 0])  # (continuation steps start where one ended)
    if not np.array_equal(handle["trajectories/initial"][...][planned], plan.initial[planned]):
        return "the initial states (--seed) differ"
    return ""
