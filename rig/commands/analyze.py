"""``impact-rig analyze``: where the model fails on a record, which named cause explains it,
and how much the extended model gains (docs/MODEL.md section 6)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from analysis import quantities as q
from rig.cli import CommandError, add_command
from rig.logs import progress

if TYPE_CHECKING:
    from analysis.discrepancy.policy import SelectionPolicy
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

A sweep is explained as one rig: FILE is a recording made by `impact-rig sweep` (its
sweep steps), a sweep exported as one CSV (its JSON lists `sweep_steps`), or several
files given together in running order: per-step files (`impact-rig export --per-step`),
and sweeps among them, each giving its steps (a forced record and the recording of the
plan `impact-rig suggest` made for it: the new record decides with the old). Each
step's dwell is a forced record with its own drive, measured from its own tach and table
channel; the rig's parameters (L, zeta, K, mu0, the barrier, the sensor's zero) are fitted
once, shared by every step, with 95 % intervals over all of them. Steps the sweep was
interrupted in, steps too short to judge (under 2 s of dwell) and steps with lost samples
are set aside with the reason. The named causes are chosen by the same forward selection
as a single record's, over every step at once, each cause's parameters shared; a cause
that explains the steps only with a different size on each is not named, and how its
size would have to vary with the drive is reported (as is a rig parameter the steps,
each fitted alone, put at different values). The report's `sweep` section (docs/MODEL.md)
lists the shared parameters, the causes and every step: setting, drive measured, regime,
residual. Then the baseline (the rig, no cause) and the explained model (the rig with
the causes named) are run through the sweep as the rig ran it, each step at its measured
drive, and their bifurcation diagrams compared with the measured one step by step (the
regimes, the stroboscopic clouds' distance in noise units, where the regime changes):
the report's `sweep.diagram` and its summary line. --report writes a page that leads with
the diagrams and a table of the steps' regimes. These simulations run on a local Dask
cluster with --workers N (N > 1) or on a scheduler's workers with --scheduler ADDRESS, as
`impact-rig map` does, with the same figures. Progress (steps identified k of n, each
fit's stage) goes to stderr.

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
  impact-rig analyze sweep_10Hz.h5 --report out/              # a sweep: one rig, every step
  impact-rig analyze sweep_step*.csv --json sweep.json        # per-step files, in this order
  impact-rig analyze first.h5 next.h5 --json both.json        # a record and its plan's steps
  impact-rig analyze sweep_10Hz.h5 --scheduler tcp://10.0.0.5:8786   # diagrams on a cluster
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
    parser.add_argument("files", type=Path, nargs="+", metavar="FILE",
                        help="exchange CSV or HDF5 recording; a sweep's recording or "
                        "exported CSV, or several files of one rig's forced steps "
                        "(per-step files, sweeps among them)")
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
        "--workers", type=int, default=None,
        help="processes fitting candidates (default: 2); a sweep's diagram simulations run "
        "on a local Dask cluster of N worker processes when N > 1 (as impact-rig map)",
    )
    parser.add_argument(
        "--scheduler", metavar="ADDRESS",
        help="a sweep: run its diagram simulations on the workers of a running Dask "
        "scheduler, e.g. tcp://127.0.0.1:8786 (as impact-rig map); the same figures as here",
    )
    parser.add_argument(
        "--rule", action="append", default=[], metavar="NAME=VALUE",
        help="change a rule that decides what is named (repeatable), e.g. bic_margin=6 or "
        "max_causes=2; the JSON report's `policy` lists every rule with its reason",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Analyse the record (or the sweep) and print a short summary (the JSON report goes to
    --json).  The files are read before the analysis is imported: a file that cannot be
    analysed is refused in a second, not after the imports."""
    from analysis.record_loaders import is_sweep

    args.file = args.files[0]
    _check_files(args)
    if is_sweep(args.files, args.meta):
        return _run_sweep(args, _policy(args))
    if args.scheduler is not None:
        raise CommandError(f"--scheduler {args.scheduler}: only a sweep's diagram runs on a "
                           "Dask scheduler; analyse a single record without it")
    record, priors = _load_record_and_priors(args)
    policy = _policy(args)
    from analysis.discrepancy import AnalysisError, analyze_record
    from analysis.identify import IdentificationError
    from analysis.report.discrepancy import report_json

    try:
        analysis = analyze_record(record, workers=args.workers, progress=progress,
                                  priors=priors, policy=policy)
    except (AnalysisError, IdentificationError, ValueError) as error:
        raise cannot_analyse(args.file, error) from error
    from analysis.report import write_report

    return _emit(report_json(analysis), analysis, write_report, _print_summary, args)


def _policy(args: argparse.Namespace) -> SelectionPolicy:
    """The selection policy with the --rule assignments."""
    from analysis.discrepancy.policy import SelectionPolicy

    try:
        return SelectionPolicy.from_assignments(args.rule)
    except ValueError as error:
        raise CommandError(f"--rule: {error}") from error


def _run_sweep(args: argparse.Namespace, policy) -> int:
    """Analyse a sweep (one rig for every step) and print its summary."""
    from analysis.sweep.load import load_sweep

    if args.free_decay or args.impact_decay:
        raise CommandError("--free-decay/--impact-decay: a sweep's steps identify the rig "
                           "themselves; analyse it without them")
    try:
        sweep = load_sweep(args.files, args.meta)
    except ValueError as error:  # the loader names the file and the step
        raise CommandError(str(error)) from error
    from analysis.discrepancy import AnalysisError
    from analysis.identify import IdentificationError
    from analysis.maps import MapRunner, SchedulerError
    from analysis.report.sweep import sweep_report_json, write_sweep_report
    from analysis.sweep.analyze import analyze_sweep

    if args.workers is not None and args.workers < 1:
        raise CommandError(f"--workers {args.workers}: need at least 1")
    # the diagram's simulations: here unless told of workers (--workers N > 1, --scheduler)
    workers = 1 if args.workers is None and args.scheduler is None else args.workers
    try:
        with MapRunner(workers, args.scheduler) as runner:
            analysis = analyze_sweep(sweep, threads=args.workers, progress=progress,
                                     policy=policy, run_map=runner.map)
    except SchedulerError as error:
        raise CommandError(str(error)) from None
    except (AnalysisError, IdentificationError, ValueError) as error:
        raise cannot_analyse(args.file, error) from error
    return _emit(sweep_report_json(analysis), analysis, write_sweep_report,
                 _print_sweep_summary, args)


def _print_sweep_summary(js: dict) -> None:
    """The shared parameters, then one line per step and per step set aside."""
    from analysis.estimate_text import estimate_text

    sweep = js["sweep"]
    print(f"sweep: {len(sweep['steps'])} steps over the drive's {sweep['parameter']}, one rig")
    for name, estimate in sweep["shared"].items():
        print(f"  {name} = {estimate_text(estimate['value'], estimate.get('ci95'))}")
    named = sweep["causes"]["named"]
    print(f"cause: {sweep['cause']}" if len(named) <= 1 else "causes: " + ", ".join(named))
    for entry in sweep["causes"]["selected"]:
        for name, estimate in entry["parameters"].items():
            print(f"  {name} = {estimate_text(estimate['value'], estimate.get('ci95'))}"
                  + ("" if entry["named"] else " (differs from step to step: not named)"))
    for step in sweep["steps"]:
        print(f"step {step['step']}: {sweep['parameter']} {step['setting']:.4g}, drive "
              f"{step['drive'][q.frequency_hz]:.6g} Hz, regime {step['regime']}, residual "
              f"{step['rms_over_noise']:.3g} x noise")
    for step in sweep["set_aside"]:
        print(f"step {step['step']} set aside: {step['reason']}")
    for finding in sweep["residual_findings"]:
        print(f"residual finding ({finding['kind']}): {finding['text']}")
    if sweep["diagram"] is not None:
        print(f"diagram: {sweep['diagram']['summary']}")
    for warning in js["warnings"]:
        print(f"caution: {warning}")


def cannot_analyse(path: Path, error: Exception) -> CommandError:
    """The one-line error of an analysis that failed, naming ``path`` once (the errors from
    below name the record they were about, often that very path)."""
    text = str(error)
    while text.startswith(f"{path}: "):
        text = text[len(f"{path}: "):]
    return CommandError(f"{path}: cannot analyse: {text}")


def _check_files(args: argparse.Namespace) -> None:
    """Refuse a missing input, a bad --workers or outputs in the way, before a long analysis."""
    from analysis.output_paths import check_outputs, record_inputs

    for path in args.files:
        if not path.exists():
            raise CommandError(f"{path}: no such file")
    if args.workers is not None and args.workers < 1:
        raise CommandError(f"--workers {args.workers}: expected at least 1")
    inputs = [p for path in args.files for p in record_inputs(path, args.meta)]
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
    from analysis.record_loaders import load_record

    try:
        record = load_record(args.file, args.meta)
        priors = None
        if args.free_decay or args.impact_decay:
            from analysis.discrepancy.analyze import priors_from_decays

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


def _emit(js: dict, analysis, write_page, summary, args: argparse.Namespace) -> int:
    """The report's JSON (with what made it) to --json or stdout, its page (Markdown and
    HTML, its JSON and figures, by ``write_page``) to --report, and the printed summary."""
    from analysis.json_output import to_json_text
    from analysis.provenance import provenance

    js["provenance"] = provenance()
    to_stdout = args.json_out == STDOUT
    if args.json_out and not to_stdout:
        _write_json(js, args.json_out, overwrite=args.overwrite)
        progress(f"wrote {args.json_out}")
    if args.report:
        try:
            page = write_page(analysis, args.report, name=args.file.stem,
                              overwrite=args.overwrite)
        except OSError as error:  # e.g. --json named the page's own JSON, written just before
            raise CommandError(f"--report {args.report}: cannot write ({error})") from None
        progress(f"wrote {page}")
    if to_stdout:
        print(to_json_text(js))
    else:
        summary(js)
    return 0
