"""The output-path guard: no command writes over an existing file unless told to, and none
ever writes over one of its own inputs, even when told to."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path


class OutputPathError(ValueError):
    """An output path that must not be written; the message names it and says why."""


HDF5_SUFFIXES = (".h5", ".hdf5")


def check_suffix(path: str | Path, suffixes: Iterable[str], what: str) -> Path:
    """``path``, after refusing a name whose extension is not one of ``suffixes`` (a
    ``what`` saved as run.csv would be opened by the wrong program, or by us as the wrong
    format)."""
    path = Path(path)
    allowed = tuple(suffixes)
    if not path.name:  # '' and '.' have no name to give a suffix to
        raise OutputPathError(f"{str(path)!r}: no file name; name {what} like "
                              f"run{allowed[0]}")
    if path.suffix.lower() not in allowed:
        raise OutputPathError(
            f"{path}: {what} is written as {' or '.join(allowed)}; name it "
            f"{path.with_suffix(allowed[0]).name}"
        )
    return path


def _same_file(a: Path, b: Path) -> bool:
    if a.exists() and b.exists():
        return os.path.samefile(a, b)
    return a.resolve() == b.resolve()


def check_outputs(
    outputs: Iterable[str | Path], *, inputs: Iterable[str | Path] = (), overwrite: bool = False
) -> list[Path]:
    """The outputs as paths, after refusing any that is an input, a folder, or (without
    ``overwrite``) an existing file.  Call before any work, so nothing is half done."""
    input_paths = [Path(p) for p in inputs]
    checked = []
    for output in map(Path, outputs):
        for source in input_paths:
            if _same_file(output, source):
                raise OutputPathError(
                    f"{output}: is an input of this command ({source}); it is never written "
                    "over, even with --overwrite: choose another name"
                )
        if output.is_dir():
            raise OutputPathError(f"{output}: is a folder; expected a file name")
        if output.exists() and not overwrite:
            raise OutputPathError(f"{output}: already exists; pass --overwrite to replace it")
        folder = output.parent if str(output.parent) else Path(".")
        if not folder.is_dir():
            raise OutputPathError(f"{output}: folder {folder} does not exist")
        checked.append(output)
    return checked


def record_inputs(path: str | Path, meta_path: str | Path | None = None) -> list[Path]:
    """The files a record is read from: an exchange CSV has its JSON sidecar as well."""
    path = Path(path)
    if meta_path is not None:
        return [path, Path(meta_path)]
    if path.suffix.lower() == ".csv":
        return [path, path.with_suffix(".json")]
    return [path]
