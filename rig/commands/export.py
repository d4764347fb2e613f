"""``impact-rig export``: a recording as CSV + JSON exchange files (docs/MODEL.md section 5)."""

from __future__ import annotations

import argparse
from pathlib import Path

from analysis import quantities as q
from rig.cli import CommandError, add_command
from rig.logs import progress

DESCRIPTION = """\
Write an HDF5 recording as the exchange format of docs/MODEL.md section 5: FILE.csv
(time_s, angle_rad, table_m, tach) and FILE.json beside it (experiment, rig
constants, drive, notes), which every analysis command and other software read.

The exchange format needs uniform sampling, so samples are never filled in:
a recording with lost samples is refused unless --gaps says what to do
(split: one FILE_segN.csv per gap-free stretch; longest: only the longest one).
--per-step writes one FILE_stepNN.csv per complete sweep step (its steady-state
dwell, with that step's drive in the JSON).
"""

EPILOG = """\
examples:
  impact-rig export run.h5 --out run.csv
  impact-rig export fsweep.h5 --out fsweep.csv --per-step
  impact-rig export lossy.h5 --out lossy.csv --gaps split
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``export`` sub-command."""
    parser = add_command(
        subparsers, "export", "recording (HDF5) -> CSV + JSON exchange files", DESCRIPTION, EPILOG
    )
    parser.add_argument("recording", metavar="FILE.h5", help="the recording to export")
    parser.add_argument(
        "--out",
        required=True,
        metavar="FILE.csv",
        help="CSV to write (FILE.json is written beside it)",
    )
    parser.add_argument(
        "--per-step", action="store_true", help="one CSV + JSON per complete sweep step"
    )
    parser.add_argument(
        "--gaps",
        choices=("refuse", "split", "longest"),
        default="refuse",
        help="what to do with a recording that lost samples (default refuse)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace existing CSV/JSON")
    parser.set_defaults(func=run)


def to_exchange(record):
    """An analysis ``Record`` as an ``ExchangeRecord`` (tach as a 0/1 column)."""
    import numpy as np

    from analysis.exchange import ExchangeMeta, ExchangeRecord, rig_constants
    from analysis.provenance import provenance

    tach = None
    if record.tach_indices.size or record.kind.driven:
        tach = np.zeros(record.time_s.size, dtype=np.int64)
        tach[record.tach_indices] = 1
    meta = ExchangeMeta(
        experiment=record.experiment,
        rig=rig_constants(record.rig),
        drive=None if record.drive is None else dict(record.drive),
        notes=record.notes,
        # the calibrations, the recording's format version, a whole sweep's steps
        extra={**record.context, "source": record.source, "provenance": provenance()},
    )
    # samples recorded as float32 are written as such: their shortest text, not the
    # float64 digits of their conversion (0.1 recorded reads 0.1, not 0.100000001490116)
    stored = np.float32 if record.context.get("samples_stored_as") == "float32" else float
    table = None if record.table_m is None else record.table_m.astype(stored)
    return ExchangeRecord(record.time_s, record.angle_rad.astype(stored), meta, table, tach)


def run(args: argparse.Namespace) -> int:
    """Load, cut (steps or segments), write; one line per file written."""
    from analysis.exchange import sidecar_path, write_exchange
    from analysis.hdf5_records import load_hdf5_segments, load_hdf5_steps
    from analysis.output_paths import check_outputs, check_suffix
    from recording.errors import RecordFormatError

    out = check_suffix(args.out, (".csv",), "the exchange table (CSV)")
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.is_dir():
        raise CommandError(f"--out {out}: folder {folder} does not exist")
    check_outputs([out, sidecar_path(out)], inputs=[args.recording], overwrite=args.overwrite)
    try:
        if args.per_step:
            records = load_hdf5_steps(args.recording)
            names = [out.with_name(f"{out.stem}_step{k:02d}.csv") for k in range(len(records))]
        else:
            records = load_hdf5_segments(args.recording)
            names = [out]
            if len(records) > 1:
                if args.gaps == "refuse":
                    raise CommandError(
                        f"{args.recording}: lost samples split it into {len(records)} gap-free "
                        "segments; the exchange format needs uniform sampling. Pass --gaps "
                        "split (one CSV per segment) or --gaps longest"
                    )
                if args.gaps == "longest":
                    records = [max(records, key=lambda r: r.time_s.size)]
                else:
                    names = [
                        out.with_name(f"{out.stem}_seg{k + 1}.csv") for k in range(len(records))
                    ]
    except RecordFormatError as error:
        raise CommandError(str(error)) from None
    check_outputs(
        [path for name in names for path in (name, sidecar_path(name))],
        inputs=[args.recording],
        overwrite=args.overwrite,
    )
    for k, (record, name) in enumerate(zip(records, names, strict=True)):
        if len(records) > 1:
            progress(f"writing {k + 1}/{len(records)} ...")
        try:
            csv_path, json_path = write_exchange(
                name, to_exchange(record), overwrite=args.overwrite
            )
        except OSError as error:  # unwritable folder, full disk: say which file, no traceback
            raise CommandError(f"{name}: cannot write ({error.strerror or error})") from None
        print(
            f"{csv_path} + {json_path.name}: {record.time_s.size} samples at "
            f"{record.sample_rate_hz:g} Hz ({record.experiment}"
            + _drive_words(record) + ")"
        )
    return 0


def _drive_words(record) -> str:
    """The drive as the line after a written file states it."""
    steps = record.context.get("sweep_steps")
    if steps:
        return f", a sweep of {len(steps)} steps: drive per step in the JSON"
    frequency = (record.drive or {}).get(q.frequency_hz)
    return f", {frequency:g} Hz drive" if frequency else ""
