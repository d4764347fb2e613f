"""``impact-rig repair``: what can still be read of a damaged, truncated or killed recording,
copied into a new recording."""

from __future__ import annotations

import argparse
from pathlib import Path

from rig.cli import add_command

DESCRIPTION = """\
Recover a recording that the other commands refuse: one that was truncated (copied
while being written, a full disk), has damaged bytes (every chunk carries a checksum,
so damage is found, never used), or was killed while recording.

The readable samples go into a NEW recording (FILE.h5 is never changed); a stretch
that cannot be read becomes a gap, exactly as a sample lost on the wire, and what was
lost is printed and kept in the new file (extra_json: repair_findings).  The new file
is closed cleanly, so any HDF5 tool opens it: this also does what 'h5clear -s' does
for a file whose writer was killed (HDF5 tools without SWMR refuse such a file with
"file is already open for write").
"""

EPILOG = """\
examples:
  impact-rig repair killed.h5 --out killed_repaired.h5
  impact-rig export killed_repaired.h5 --out killed.csv --gaps split
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``repair`` sub-command."""
    parser = add_command(
        subparsers,
        "repair",
        "recover what can be read of a damaged or killed recording into a new file",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument("recording", type=Path, metavar="FILE.h5", help="the damaged recording")
    parser.add_argument(
        "--out", type=Path, metavar="NEW.h5",
        help="the repaired copy to write (default FILE_repaired.h5 beside FILE.h5)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace an existing NEW.h5")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Salvage into the new file and say what was lost."""
    from analysis.output_paths import HDF5_SUFFIXES, check_outputs, check_suffix
    from analysis.provenance import provenance
    from recording.repair import repair_recording
    from recording.superblock import read_superblock

    read_superblock(args.recording)  # no such file, a folder, no HDF5: refused before --out
    out = args.out or args.recording.with_name(f"{args.recording.stem}_repaired.h5")
    check_suffix(out, HDF5_SUFFIXES, "the repaired recording (HDF5)")
    (out,) = check_outputs([out], inputs=[args.recording], overwrite=args.overwrite)
    if out.exists():
        out.unlink()  # --overwrite was given (and it is not the input)
    print(repair_recording(args.recording, out, provenance=provenance()).summary())
    return 0
