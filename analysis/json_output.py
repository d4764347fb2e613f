"""The one JSON writer: every report, sidecar, printed report and JSON-valued attribute the
software writes goes through here, so that all follow one rule (docs/MODEL.md section 8).

The rule: a float that is not finite (NaN, +inf, -inf) is written as ``null``, "no value",
so the text is strict JSON (RFC 8259) that every reader parses.  numpy scalars and arrays
become numbers and lists, tuples lists, paths their text, and mapping keys text.  Files are
UTF-8, indented by two spaces and end in a newline; JSON kept inside another file (an HDF5
attribute, a PNG text chunk, a log line) is one line.  A file that exists is never written
over unless the caller says so.

A leaf module: it imports nothing of the project, so that any of it may use it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

INDENT = 2


def json_ready(value: Any) -> Any:
    """A copy of ``value`` made of JSON's own types, non-finite floats as None (the rule
    above); a value of any other type is left for the encoder to refuse."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(key): json_ready(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(item) for item in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, Path):
        return str(value)
    return value


def to_json_text(value: Any, *, one_line: bool = False) -> str:
    """``value`` as strict JSON text (without a final newline): indented, or on one line for
    text held inside another file."""
    return json.dumps(
        json_ready(value),
        indent=None if one_line else INDENT,
        ensure_ascii=False,
        allow_nan=False,
    )


def write_json(path: str | Path, value: Any, *, overwrite: bool = False) -> Path:
    """Write ``value`` to ``path`` as JSON text and a newline; FileExistsError when the file
    exists and ``overwrite`` is not given.  Returns the path."""
    path = Path(path)
    text = to_json_text(value) + "\n"  # before opening: a value that cannot be written
    with path.open("w" if overwrite else "x", encoding="utf-8") as handle:  # leaves no file
        handle.write(text)
    return path
