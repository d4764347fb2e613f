"""The errors of reading a file as a recording: not one (a format error), or one that is damaged."""

from __future__ import annotations

REPAIR_HINT = "'impact-rig repair {path}' recovers what can still be read"


class RecordFormatError(ValueError):
    """A file cannot be turned into a record; the message names the file and what was wrong.

    Every reader of a file raises it (the analysis's CSV and exchange readers too), so that a
    command reports a file it cannot read in one line; it is defined here, below all of them.
    """


class RecordingFormatError(RecordFormatError):
    """The file is not a readable impact-rig recording; the message names the file and the part."""


class RecordingDamagedError(RecordingFormatError):
    """The file is a recording, but truncated or with damaged bytes (checksum failures)."""


def first_line(error: BaseException) -> str:
    """The first line of an error's message (HDF5's run on), or its type's name when it has none."""
    return str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
