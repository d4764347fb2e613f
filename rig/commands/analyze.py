"""``impact-rig analyze``: where the model fails on a record, which named cause explains it,
and how much the extended model gains (docs/MODEL.md section 6)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from rig.cli import CommandError, add_command
from rig.logs import progress

if TYPE_CHECKING:
    from analysis.records import Record

DESCRIPTION = """\
Explain a measured record: fit the baseline model of docs/MODEL.md section 2, show where it
fails (phase of motion, angle, velocity, envelope, spectrum), fit every named cause of
docs/MODEL.md section 6 that can show in this kind of experiment as an extension of the model,
and choose the one that earns its keep on two counts: the information criterion (BIC with
the data's own noise level and effective sample count) and the prediction of data the fit
did not see. `none` when no extension helps clearly.

Decays are fitted point by point on their first part and predict the rest. Impact decays
also compare the paper's finite-time (Hunt-Crossley) contact with a constant coefficient
of restitution.

A forced record is explained on its own: its regime (period k, chaotic, ...) is judged
from stroboscopic samples locked to the tach, aware of the noise; the drive's frequency,
phase and amplitude come from the tach and the table channel and are compared with the
stated ones; every model is identified from the record (equation error, then multiple
shooting over short segments, then over the whole record), and judged by forecasts of
the stretch after each fitted one (and, on a chaotic record, by the invariant statistics
of the model's own long run). Decay records, when given, only start the fit.

FILE is an exchange CSV (NAME.json beside it, or --meta) or an HDF5 recording.
"""

EPILOG = """\
examples:
  impact-rig analyze decay.csv
  impact-rig analyze impacts.csv --json impacts_analysis.json --report out/
  impact-rig analyze run.h5 --workers 1
  impact-rig analyze forced.csv --report out/
  impact-rig analyze forced.csv --impact-decay impacts.csv   # start from the decay's values
  impact-rig analyze decay.csv --rule bic_margin=6            # a looser information criterion
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``analyze`` sub-command."""
    parser = add_command(
        subparsers,
        "analyze",
        "find what the model gets wrong on a record and the gain of the fix",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument("file", type=Path, help="exchange CSV or HDF5 recording")
    parser.add_argument("--meta", type=Path, help="JSON sidecar, if not NAME.json beside FILE")
    parser.add_argument(
        "--json", type=Path, dest="json_out", metavar="FILE",
        help="write the full JSON report to FILE ('-': to stdout instead of the summary)",
    )
    parser.add_argument("--report", type=Path,
                        help="write the report page (Markdown and HTML) with figures here")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace existing --json and report files"
    )
    parser.add_argument(
        "--free-decay", type=Path, dest="free_decay",
        help="forced records: a free decay of the same rig (CSV/HDF5); its L and zeta only "
        "start the fit",
    )
    parser.add_argument(
        "--impact-decay", type=Path, dest="impact_decay",
        help="forced records: an impact decay of the same rig; its K and mu0 only start the fit",
    )
    parser.add_argument(
        "--workers", type=int, default=None, help="processes fitting candidates (default: 2)"
    )
    parser.add_argument(
        "--rule", action="append", default=[], metavar="NAME=VALUE",
        help="change a rule that decides what is named (repeatable), e.g. bic_margin=6 or "
        "max_causes=2; the JSON report's `policy` lists every rule with its reason",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Analyse the record and print a short summary (the JSON report goes to --json)."""
    from analysis.discrepancy import AnalysisError, SelectionPolicy, analyze_record
    from analysis.identify import IdentificationError
    from analysis.json_output import to_json_text
    from analysis.provenance import provenance
    from analysis.report.discrepancy import report_json

    _check_files(args)
    try:
        policy = SelectionPolicy.from_assignments(args.rule)
    except ValueError as error:
        raise CommandError(f"--rule: {error}") from error
    record, priors = _load_record_and_priors(args)
    try:
        analysis = analyze_record(record, workers=args.workers, progress=progress,
                                  priors=priors, policy=policy)
    except (AnalysisError, IdentificationError, ValueError) as error:
        raise CommandError(f"{args.file}: cannot analyse: {error}") from error
    js = report_json(analysis)
    js["provenance"] = provenance()
    to_stdout = args.json_out == STDOUT
    if args.json_out and not to_stdout:
        _write_json(js, args.json_out, overwrite=args.overwrite)
        progress(f"wrote {args.json_out}")
    if args.report:
        progress(f"wrote {_write_report(analysis, args)}")
    if to_stdout:
        print(to_json_text(js))
    else:
        _print_summary(js)
    return 0


def _check_files(args: argparse.Namespace) -> None:
    """Refuse a missing input, a bad --workers or outputs in the way, before a long analysis."""
    from analysis.output_paths import check_outputs, record_inputs

    if not args.file.exists():
        raise CommandError(f"{args.file}: no such file")
    if args.workers is not None and args.workers < 1:
        raise CommandError(f"--workers {args.workers}: expected at least 1")
    inputs = record_inputs(args.file, args.meta)
    for decay in (args.free_decay, args.impact_decay):
        inputs += record_inputs(decay) if decay else []
    outputs = [args.json_out] if args.json_out and args.json_out != STDOUT else []
    if args.report and args.report.exists():  # a new folder is made by write_report
        if not args.report.is_dir():
            raise CommandError(f"--report {args.report}: is a file; expected a folder")
        outputs += report_files(args.report, args.file.stem)
    check_outputs(outputs, inputs=inputs, overwrite=args.overwrite)


def _load_record_and_priors(
    args: argparse.Namespace,
) -> tuple[Record, dict[str, float] | None]:
    """The record, and the start values from --free-decay and --impact-decay (None without)."""
    from analysis.discrepancy.analyze import priors_from_decays
    from analysis.record_loaders import load_record

    try:
        record = load_record(args.file, args.meta)
        priors = None
        if args.free_decay or args.impact_decay:
            priors = priors_from_decays(
                load_record(args.free_decay) if args.free_decay else None,
                load_record(args.impact_decay) if args.impact_decay else None,
            )
            progress(f"start values from the decays: {priors}")
    except ValueError as error:  # a file's format error names the file and field itself
        raise CommandError(str(error)) from error
    return record, priors


def _print_summary(js: dict) -> None:
    """The verdict in a few lines: the causes with their sizes, the fit against the noise,
    the regime, what is left; the full report is the JSON's."""
    from analysis.estimate_text import estimate_text

    if len(js["causes"]) > 1:
        print("causes: " + ", ".join(c["cause"] for c in js["causes"]))
    else:
        print(f"cause: {js['cause']}")
    for step in js["causes"]:
        for name, estimate in step["parameters"].items():
            print(f"  {name} = {estimate_text(estimate['value'], estimate.get('ci95'))}")
    noise = js["noise_rad"]
    fits = [("baseline", js["baseline"]["rms_residual"])]
    if js["causes"]:
        fits.append(("with " + " + ".join(c["cause"] for c in js["causes"]),
                     js["extended"]["rms_residual"]))
    for label, rms in fits:
        print(f"{label} fit: rms residual {rms:.3g} rad = {rms / noise:.3g} x the noise")
    if js.get("regime"):
        print(f"regime: {js['regime']['label']}")
    if js.get("unexplained"):
        print("the model still misses something: see the residual findings")
    for pair in js.get("indistinct", []):
        print(f"cannot tell apart: {pair['why']}")
    for finding in js.get("residual_findings", []):
        print(f"residual finding ({finding['kind']}): {finding['text']}")
    for term in js.get("proposed_terms", []):
        print(term["text"])
    print(f"where the baseline fails: {js['localization']}")
    for warning in js["warnings"]:
        print(f"caution: {warning}")


STDOUT = Path("-")  # --json -: the report to standard output


def report_files(folder: Path, name: str) -> list[Path]:
    """The files ``analysis.report.write_report`` writes into ``folder`` for record ``name``."""
    return [folder / f"{name}{suffix}" for suffix in (".md", ".html", ".json", "_fit.png",
                                                       "_restitution.png")]


def _write_json(report: dict, path: Path, *, overwrite: bool) -> None:
    from analysis.json_output import write_json

    try:
        write_json(path, report, overwrite=overwrite)
    except OSError as error:
        raise CommandError(f"{path}: cannot write ({error.strerror or error})") from None


def _write_report(analysis, args: argparse.Namespace) -> Path:
    """The page (Markdown and HTML), its JSON and figures in --report; returns the .md path."""
    from analysis.report import write_report

    try:
        return write_report(analysis, args.report, name=args.file.stem, overwrite=args.overwrite)
    except OSError as error:  # e.g. --json named the page's own JSON, written just before
        raise CommandError(f"--report {args.report}: cannot write ({error})") from None
