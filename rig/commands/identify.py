"""``impact-rig identify``: identify model parameters from a recording or an exchange CSV."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from analysis import quantities as q
from rig.cli import CommandError, add_command
from rig.logs import progress

if TYPE_CHECKING:
    from analysis.identify import IdentificationResult
    from analysis.records import Record

DESCRIPTION = """\
Identify the model parameters of a record (docs/MODEL.md section 7 keys, 95 % intervals
from the Jacobian, widened for correlated residuals by a Newey-West sandwich).

The experiment named in the metadata decides the fit:
  free_decay    L (= g / omega^2, the effective length), zeta, theta0 and sensor offset;
                averaging solution up to 0.2 rad amplitude, full simulation beyond
  impact_decay  K (and E for the rig's R), mu0, theta_b by simulating the record;
                L and zeta held with --hold or --free-decay, else fitted too
  forced        everything the record determines on its own: L, zeta, K (and E), mu0,
                the barrier position and sensor zero, the drive's frequency and phase
                (tach) and amplitude (table channel, else fitted); start values by
                equation error in free flight, then multiple shooting over the record.
                --hold and --free-decay values only start the fit (priors), they are
                not held

Bad samples (NaN, spikes), a start before the release and a tail at rest are found
and reported. A poor fit is reported as such, not hidden.
"""

EPILOG = """\
examples:
  impact-rig identify run.csv --json run_params.json
  impact-rig identify impacts.csv --free-decay decay.csv
  impact-rig identify impacts.csv --hold L_m=0.046,zeta=0.007
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``identify`` sub-command."""
    parser = add_command(
        subparsers,
        "identify",
        "identify model parameters of a record (exchange CSV + JSON, or HDF5)",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument(
        "files", type=Path, nargs="+", metavar="FILE",
        help="exchange CSV (NAME.json beside it) or HDF5 recording; several free decays of "
        "one pendulum are fitted one by one and pooled (inverse-variance, Birge-widened)",
    )
    parser.add_argument("--meta", type=Path, help="JSON sidecar, if not NAME.json beside FILE")
    parser.add_argument("--json", type=Path, dest="json_out", help="write the report here")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --json file")
    parser.add_argument(
        "--hold",
        default="",
        help="impact decay: hold parameters, e.g. L_m=0.046,zeta=0.007 (forced: start values)",
    )
    parser.add_argument(
        "--free-decay",
        type=Path,
        dest="free_decay",
        help="impact decay: take L and zeta from this free-decay record (CSV or HDF5); "
        "forced: start from them",
    )
    parser.set_defaults(func=run)


def _parse_hold(text: str) -> dict[str, float]:
    hold: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, sep, value = item.partition("=")
        if not sep:
            raise CommandError(f"--hold: {item!r} is not KEY=VALUE")
        try:
            hold[key.strip()] = float(value)
        except ValueError:
            raise CommandError(f"--hold: {key.strip()} = {value!r} is not a number") from None
    return hold


def run(args: argparse.Namespace) -> int:
    """Load the record, run the fit its experiment calls for, print and save the report.
    The files are read before the fits are imported: a file that cannot be read is refused
    in a second."""
    from analysis.experiments import FREE_DECAY
    from analysis.json_output import write_json
    from analysis.output_paths import check_outputs, record_inputs
    from analysis.provenance import provenance
    from analysis.record_loaders import load_record

    if len(args.files) > 1 and args.meta:
        raise CommandError("--meta applies to a single FILE; give each CSV its NAME.json")
    if args.json_out:  # refused before a long fit: an existing file, an input, no folder
        inputs = [p for path in args.files for p in record_inputs(path, args.meta)]
        inputs += [args.free_decay] if args.free_decay else []
        check_outputs([args.json_out], inputs=inputs, overwrite=args.overwrite)
    try:
        records = [load_record(path, args.meta) for path in args.files]
    except ValueError as error:  # format errors name the file and field themselves
        raise CommandError(str(error)) from None
    from analysis.identify import IdentificationError, fit_free_decay, pool_free_decays

    try:
        if len(records) > 1:
            kinds = {r.experiment for r in records}
            if kinds != {FREE_DECAY.name}:
                raise CommandError(
                    f"several files can only be pooled as free decays; got {sorted(kinds)}"
                )
            fits = []
            for path, record in zip(args.files, records, strict=True):
                progress(f"identifying {path} ({record.time_s.size} samples)...")
                try:
                    fits.append(fit_free_decay(record))
                except IdentificationError as error:
                    raise CommandError(f"{path}: cannot identify: {error}") from None
            result = pool_free_decays(fits)
        else:
            result = _identify_one(args, records[0])
    except IdentificationError as error:
        raise CommandError(f"{args.files[0]}: cannot identify: {error}") from None
    except ValueError as error:  # format errors name the file and field themselves
        raise CommandError(str(error)) from None
    print(result.summary())
    if args.json_out:
        report = result.as_json()
        report["source"] = [str(path) for path in args.files]
        report["provenance"] = provenance()
        try:
            write_json(args.json_out, report, overwrite=args.overwrite)
        except OSError as error:
            raise CommandError(f"--json {args.json_out}: cannot write ({error.strerror})") from None
        print(f"report written to {args.json_out}")
    return 0


def _identify_one(args: argparse.Namespace, record: Record) -> IdentificationResult:
    """The fit that the record's experiment calls for."""
    import math

    from analysis.experiments import FREE_DECAY
    from analysis.identify import (
        IdentificationError,
        fit_forced,
        fit_free_decay,
        fit_impact_decay,
    )
    from analysis.record_loaders import load_record

    progress(f"identifying {record.source} ({record.experiment}, {record.time_s.size} "
             "samples)...")
    kind = record.kind
    if kind is FREE_DECAY:
        return fit_free_decay(record)
    hold = _parse_hold(args.hold)
    if args.free_decay:
        decay_record = load_record(args.free_decay)
        if decay_record.kind is not FREE_DECAY:
            raise CommandError(
                f"--free-decay {args.free_decay}: its experiment is {decay_record.experiment}, "
                "not free_decay"
            )
        try:
            decay = fit_free_decay(decay_record)
        except IdentificationError as error:
            raise CommandError(
                f"--free-decay {args.free_decay}: cannot identify: {error}"
            ) from None
        hold.setdefault(q.L_m, decay[q.L_m].value)
        hold.setdefault(q.zeta, decay[q.zeta].value)
    if not kind.driven:
        return fit_impact_decay(record, hold=hold)
    unknown = sorted(set(hold) - {q.L_m, q.zeta, q.K_N_per_m1_5, q.mu0_s_per_m})
    if unknown:
        raise CommandError(f"--hold: {unknown} cannot start a forced fit; use L_m, zeta, "
                           "K_N_per_m1.5 or mu0_s_per_m")
    priors = {k: v for k, v in hold.items() if k != q.L_m}
    if q.L_m in hold:
        priors[q.omega_rad_s] = math.sqrt(record.gravity_m_s2 / hold[q.L_m])
    return fit_forced(record, priors=priors,
                      progress=lambda text: progress(f"  {text}"))
