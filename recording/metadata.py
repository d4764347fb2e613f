"""A recording's metadata, the root attributes that let it be analysed years later: one type,
and the one mapping between its fields and the file's attributes."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import h5py

from analysis.json_output import to_json_text
from recording.layout import FORMAT_NAME, FORMAT_VERSION


@dataclass(frozen=True)
class RecordingMetadata:
    """What a recording must carry to be analysed years later (root attributes of the file)."""

    experiment: str
    notes: str = ""
    rig: dict[str, float | None] = field(default_factory=dict)
    calibrations: dict[str, Any] = field(default_factory=dict)
    devices: dict[str, Any] = field(default_factory=dict)
    config_toml: str = ""
    drive: dict[str, float] | None = None
    roles: dict[str, str] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)
    start_time_utc: str = ""
    provenance: dict[str, Any] = field(default_factory=dict)  # analysis.provenance


@dataclass(frozen=True)
class RecordingInfo(RecordingMetadata):
    """The recording's metadata (root attributes), decoded, with the software and format
    version that wrote it."""

    software_version: str = ""
    format_version: int = 0


# The metadata fields in the order their root attributes are written (docs/recording_layout.md,
# "Root attributes"); a field kept as JSON text is stored as the attribute ``<field>_json``.
JSON_FIELDS = ("rig", "calibrations", "devices", "drive", "roles", "extra", "provenance")
STORED_FIELDS = (
    "start_time_utc", "experiment", "notes", "rig", "calibrations", "devices", "config_toml",
    "drive", "roles", "extra", "provenance",
)
EMPTY_JSON: dict[str, type] = {"drive": type(None)}  # what a missing JSON field reads as: {} else


def json_attribute(value: Any) -> str:
    """``value`` as the text of a JSON attribute: strict JSON on one line."""
    return to_json_text(value, one_line=True)


def attribute_name(field_name: str) -> str:
    """The root attribute that holds metadata field ``field_name``."""
    return f"{field_name}_json" if field_name in JSON_FIELDS else field_name


def metadata_attributes(meta: RecordingMetadata, software_version: str) -> dict[str, Any]:
    """The root attributes that hold ``meta`` (docs/recording_layout.md, "Root attributes")."""
    stored = {
        attribute_name(name): (
            json_attribute(getattr(meta, name))
            if name in JSON_FIELDS
            else getattr(meta, name)
        )
        for name in STORED_FIELDS
    }
    return {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "software_version": software_version,
        **stored,
    }


def metadata_fields(
    attrs: Mapping[str, Any], decode_json: Callable[[str, Any], Any]
) -> dict[str, Any]:
    """The :class:`RecordingMetadata` fields held in root attributes ``attrs`` (as
    :func:`read_attributes` returns them): text as it is ('' when missing), JSON fields
    through ``decode_json(attribute, default)``, the default an empty mapping (None for the
    drive).  The caller decides what JSON that does not parse means: an error or a finding."""
    return {
        name: (
            decode_json(attribute_name(name), EMPTY_JSON.get(name, dict)())
            if name in JSON_FIELDS
            else str(attrs.get(name, ""))
        )
        for name in STORED_FIELDS
    }


def carried_over(
    info: RecordingMetadata, *, extra: Mapping[str, Any], provenance: Mapping[str, Any]
) -> RecordingMetadata:
    """The metadata of a new recording made from an existing one (a replay recorded anew):
    everything ``info`` says of the rig, the run and its channels, with the new file's own
    ``extra`` and ``provenance``, and no start time (the new recording's is its own)."""
    kept = {name: getattr(info, name) for name in STORED_FIELDS}
    return RecordingMetadata(
        **{**kept, "start_time_utc": "", "extra": dict(extra), "provenance": dict(provenance)}
    )


def write_attributes(node: h5py.HLObject, values: dict[str, Any]) -> None:
    """Set ``node``'s attributes, text as fixed-length UTF-8 strings.  Those are kept with the
    attribute itself, under HDF5's metadata checksums; a variable-length string lives in the
    global heap, which has none (zeroed bytes there sent HDF5 into an endless loop)."""
    for key, value in values.items():
        if isinstance(value, str):
            data = value.encode("utf-8")
            node.attrs.create(key, data, dtype=h5py.string_dtype("utf-8", max(1, len(data))))
        else:
            node.attrs[key] = value


def read_attributes(node: h5py.HLObject) -> dict[str, Any]:
    """``node``'s attributes, text as ``str`` whether stored fixed-length or variable-length."""
    return {
        key: value.decode("utf-8", "replace") if isinstance(value, bytes) else value
        for key, value in node.attrs.items()
    }

