"""``impact-rig simulate``: simulate the impact pendulum and write a record (CSV + JSON or HDF5).

The CSV output is the exchange format of docs/MODEL.md section 5 (``time_s``, ``angle_rad``,
and for forced runs ``table_m`` and ``tach``; the JSON sidecar beside it), so every
analysis command reads a simulated record like a measured one.

HDF5 output (``.h5``/``.hdf5``) is a recording in the recorder's layout
(docs/recording_layout.md), written through :mod:`recording.writer`: channels ``angle``
(and ``table`` and the pulse channel ``tach`` for forced runs), the drive, and
``"source": "simulated"`` in its ``extra_json``; so ``replay``, ``export``, ``identify``
and ``analyze`` read it like any recording.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from analysis import quantities as q
from analysis.experiments import FORCED, IMPACT_DECAY, NAMES, experiment_kind
from rig.cli import CommandError, add_command
from rig.logs import log, progress

DRIVE_PARAMETERS = {
    q.f_drive_hz: "drive frequency [Hz]",
    q.A_m: "table displacement amplitude [m]",
    q.beta: "amplitude as a fraction of L (A = beta L)",
}
NONDIMENSIONAL_PARAMETERS = {
    q.eta: "omega / Omega (sets L, needs the drive frequency)",
    q.mu: "mu0 l Omega (sets mu0)",
    q.gamma: "K l^2.5 / (m Omega^2 L^2) (sets E for the rig's R)",
}
MAX_SAMPLES = 50_000_000

DESCRIPTION = """\
Simulate the impact pendulum (docs/MODEL.md section 2) and write the record.

Parameters start from the paper's rig (docs/MODEL.md section 3) or, with --case, from the
paper's nondimensional values for that forced case; --param changes any of them.
The experiment decides barrier and drive:
  free_decay    no barrier, no drive (the pendulum swings freely from --theta0)
  impact_decay  barrier, no drive (released at --theta0, it rattles to rest)
  forced        barrier and table drive (needs f_drive_hz and A_m or beta, or --case)

Output: FILE.csv + FILE.json (exchange format) or FILE.h5 (a recording in the layout of
docs/recording_layout.md: channels angle, table and tach, source simulated; the values are
stored as float32 there, as the recorder stores them). time_s starts at 0 at the end of the
skipped transient; for forced runs that is a whole number of drive periods, so the
drive phase is Omega time_s and tach = 1 on the sample nearest each phase-0 instant.
The angle is the noise-free model angle unless a measurement model is asked for
(--noise-rad, --quantization-rad, or a sensor cause such as sensor_offset).
"""

EPILOG = """\
parameters (--param NAME=VALUE, SI units in the names):
  rig        m_kg l_m L_m R_m g_m_s2 zeta E_Pa mu0_s_per_m theta_b_rad
  drive      f_drive_hz A_m beta
  paper      eta mu gamma (with the drive frequency; applied after the rig values)
  causes     parameters of the named causes of docs/MODEL.md section 6, e.g. Tc_N_m
             (coulomb_friction), c2_per_rad, n and K_n, c_N_s_per_m, h2 phi2_rad, eps,
             offset_rad, k3, tau_s; giving one switches its cause on (as --cause does)

examples:
  impact-rig simulate --case h --skip 10 --duration 20 --fs 2000 --out case_h.csv
  impact-rig simulate --experiment impact_decay --theta0 -1.2 --duration 5 --fs 20000 \\
      --out impacts.csv
  impact-rig simulate --experiment free_decay --theta0 0.1 --param zeta=0.01 --out decay.h5
  impact-rig simulate --experiment forced --param f_drive_hz=10 --param beta=0.03 \\
      --cause coulomb_friction --param Tc_N_m=1e-5 --noise-rad 2e-4 --seed 1 --out run.csv
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` sub-command."""
    parser = add_command(
        subparsers,
        "simulate",
        "simulate the pendulum and write CSV + JSON or HDF5",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument(
        "--experiment",
        choices=NAMES,
        help="free_decay, impact_decay or forced (default: forced with --case or drive "
        "parameters, else impact_decay)",
    )
    parser.add_argument("--case", help="one of the paper's forced cases a..i (implies forced)")
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set a parameter (repeatable; names below)",
    )
    parser.add_argument(
        "--cause",
        action="append",
        default=[],
        metavar="NAME",
        help="switch on a named cause of docs/MODEL.md section 6 (repeatable)",
    )
    parser.add_argument("--theta0", type=float, default=-0.3, help="initial angle [rad] (-0.3)")
    parser.add_argument(
        "--omega0", type=float, default=0.0, help="initial angular velocity theta' [rad/s] (0)"
    )
    parser.add_argument("--duration", type=float, default=10.0, help="recorded time [s] (10)")
    parser.add_argument("--fs", type=float, default=1000.0, help="sample rate [Hz] (1000)")
    parser.add_argument(
        "--skip",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="transient simulated and discarded first, rounded up to whole drive periods (0)",
    )
    parser.add_argument(
        "--out", type=Path, required=True, help="output FILE.csv (+ FILE.json) or FILE.h5"
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace an existing output file (and sidecar)"
    )
    parser.add_argument("--noise-rad", type=float, default=0.0, help="angle noise std [rad]")
    parser.add_argument(
        "--quantization-rad", type=float, default=0.0, help="angle quantization step [rad]"
    )
    parser.add_argument("--seed", type=int, help="seed of the measurement noise")
    parser.add_argument(
        "--lyapunov", action="store_true",
        help="also the model's Lyapunov spectrum over the recorded span (the transient "
        "turns the frame without counting): both exponents by the QR method on the exact "
        "sensitivities, with their convergence; printed and in the JSON (not with Coulomb "
        "friction)",
    )
    parser.add_argument(
        "--rtol", type=float, default=1e-9,
        help="integrator relative tolerance (1e-9); the absolute one is rtol / 100",
    )
    parser.set_defaults(func=run)


# --------------------------------------------------------------------------- parameters


def parse_assignments(items: list[str]) -> dict[str, float]:
    """``["NAME=VALUE", ...]`` -> {NAME: float}, with clear errors."""
    values: dict[str, float] = {}
    for item in items:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise CommandError(f"--param {item!r}: expected NAME=VALUE, e.g. L_m=0.046")
        try:
            value = float(text)
        except ValueError:
            raise CommandError(f"--param {name}: {text.strip()!r} is not a number") from None
        if not math.isfinite(value):
            raise CommandError(f"--param {name}: {text.strip()!r} is not a finite number")
        values[name] = value
    return values


def _cause_parameters(rig_names: list[str]) -> dict[str, str]:
    """Parameter name -> the named cause it belongs to (rig parameters excluded)."""
    from analysis.extensions import CAUSES

    return {
        spec.name: c.name
        for c in CAUSES.values()
        for spec in c.parameters
        if spec.name not in rig_names
    }


def parameter_names() -> list[str]:
    """Every name --param takes: rig, drive, nondimensional, then the causes' parameters."""
    from dataclasses import fields

    from analysis.model import RigParameters

    rig_names = [f.name for f in fields(RigParameters)]
    causes = sorted(_cause_parameters(rig_names))
    return [*rig_names, *DRIVE_PARAMETERS, *NONDIMENSIONAL_PARAMETERS, *causes]


def build_model(
    case: str | None, experiment: str | None, params: dict[str, float], causes: list[str]
) -> tuple[Any, str]:
    """The Model and experiment name the options describe (CommandError when inconsistent)."""
    from dataclasses import fields

    from analysis.model import Model, RigParameters
    from analysis.packed import ParameterError

    rig_names = [f.name for f in fields(RigParameters)]
    experiment = _checked_experiment(case, experiment, params, causes)
    kind = experiment_kind(experiment)
    try:
        rig, drive = _rig_and_drive(case, kind.driven, params, rig_names)
        model = Model(rig, drive, barrier=kind.barrier)
        for name, values in _switched_on_causes(params, causes, rig_names).items():
            model = model.with_extension(name, **values)
    except ParameterError as error:
        raise CommandError(str(error)) from None
    return model, experiment


def _checked_experiment(
    case: str | None, experiment: str | None, params: dict[str, float], causes: list[str]
) -> str:
    """The experiment's name (forced with --case or a drive, else impact_decay), once the
    parameter and cause names are known and fit it."""
    from analysis.extensions import CAUSES

    valid = parameter_names()
    unknown = [name for name in params if name not in valid]
    if unknown:
        raise CommandError(
            f"unknown parameter(s) {', '.join(unknown)}; valid names: {', '.join(valid)}"
        )
    for name in causes:
        if name not in CAUSES:
            raise CommandError(f"unknown cause {name!r}; known: {', '.join(sorted(CAUSES))}")
    drive_given = any(name in params for name in DRIVE_PARAMETERS)
    if experiment is None:
        experiment = (FORCED if (case or drive_given) else IMPACT_DECAY).name
    kind = experiment_kind(experiment)
    if case and not kind.driven:
        raise CommandError(f"--case {case} is a forced case; it cannot run as {experiment}")
    if not kind.driven and (
        drive_given or any(n in params for n in NONDIMENSIONAL_PARAMETERS)
    ):
        raise CommandError(
            f"drive or nondimensional parameters given for the unforced {experiment} experiment"
        )
    return experiment


def _rig_and_drive(
    case: str | None, driven: bool, params: dict[str, float], rig_names: list[str]
) -> tuple[Any, Any]:
    """The rig and drive: the paper's case (or the default rig), then the rig values, the
    nondimensional ones and the drive's given in ``params``, in that order."""
    from dataclasses import replace

    from analysis.model import (
        Drive,
        RigParameters,
        from_nondimensional,
        paper_case,
        to_nondimensional,
    )

    rig, frequency, amplitude = RigParameters(), 0.0, 0.0
    if case:
        rig, drive = paper_case(case).dimensional()
        frequency, amplitude = drive.frequency_hz, drive.amplitude_m
    rig = rig.with_values(**{k: v for k, v in params.items() if k in rig_names})
    frequency = params.get(q.f_drive_hz, frequency)
    nondimensional = {k: v for k, v in params.items() if k in NONDIMENSIONAL_PARAMETERS}
    if nondimensional:
        if frequency <= 0:
            raise CommandError("eta, mu and gamma need the drive frequency (f_drive_hz)")
        beta = amplitude / rig.L_m
        nd = replace(to_nondimensional(rig, Drive(0.0, frequency)), **nondimensional)
        rig, _ = from_nondimensional(nd, frequency, rig)
        amplitude = beta * rig.L_m
    if q.beta in params:
        amplitude = params[q.beta] * rig.L_m
    amplitude = params.get(q.A_m, amplitude)
    if not driven:
        return rig, Drive()
    if frequency <= 0 or amplitude <= 0:
        raise CommandError(
            "a forced run needs a drive: --case, or --param f_drive_hz=... with "
            "--param A_m=... or --param beta=..."
        )
    return rig, Drive(amplitude_m=amplitude, frequency_hz=frequency)


def _switched_on_causes(
    params: dict[str, float], causes: list[str], rig_names: list[str]
) -> dict[str, dict[str, float]]:
    """Each cause switched on (by --cause or by one of its parameters) with its given values."""
    cause_of = _cause_parameters(rig_names)
    extensions: dict[str, dict[str, float]] = {name: {} for name in causes}
    for name, value in params.items():
        if name in cause_of:
            extensions.setdefault(cause_of[name], {})[name] = value
    return extensions


# --------------------------------------------------------------------------- output


def _metadata(model: Any, experiment: str, args: argparse.Namespace, extra: dict) -> Any:
    from analysis.exchange import ExchangeMeta
    from analysis.provenance import provenance

    rig = model.rig
    drive = None
    if experiment_kind(experiment).driven:
        drive = {
            q.frequency_hz: model.drive.frequency_hz,
            q.amplitude_m: model.drive.amplitude_m,
        }
    return ExchangeMeta(
        experiment=experiment,
        rig={q.m_kg: rig.m_kg, q.l_m: rig.l_m, q.R_m: rig.R_m, "g": rig.g_m_s2},
        drive=drive,
        notes=f"simulated by impact-rig simulate ({' '.join(sys.argv[1:]) or 'library call'})",
        extra={"simulation": extra, "provenance": provenance()},
    )


def _write_recording(
    path: Path, columns: dict[str, Any], meta: Any, fs_hz: float, overwrite: bool
) -> None:
    """The simulated record as a recording (docs/recording_layout.md): one block per channel,
    no gaps, a closed file; ``raw`` holds no ADC counts (there is no ADC), only zeros."""
    from datetime import UTC, datetime

    import numpy as np

    from recording.layout import ChannelSpec, RecordingStatus
    from recording.metadata import RecordingMetadata
    from recording.writer import RecordingWriter
    from rig.devices import ANGLE, TABLE, TACH
    from rig.recorder import software_version

    n = columns["angle_rad"].size
    sampled = {ANGLE: ("rad", columns["angle_rad"])}
    if columns["table_m"] is not None:
        sampled[TABLE] = ("m", columns["table_m"])
    tach = columns["tach"]
    device = "simulated (impact-rig simulate)"
    specs = [ChannelSpec(name, "samples", unit, fs_hz, device, raw_dtype="int8")
             for name, (unit, _) in sampled.items()]
    specs += [ChannelSpec(TACH, "pulses", "", fs_hz, device)] if tach is not None else []
    stored = RecordingMetadata(
        experiment=meta.experiment,
        notes=meta.notes,
        rig=dict(meta.rig),
        drive=meta.drive,
        roles={spec.name: spec.name for spec in specs},
        extra={"source": "simulated", **{k: v for k, v in meta.extra.items()
                                         if k != "provenance"}},
        start_time_utc=datetime.now(UTC).isoformat(),
        provenance=meta.extra["provenance"],
    )
    if overwrite:
        path.unlink(missing_ok=True)  # an existing file was refused unless --overwrite
    writer = RecordingWriter(path, specs, stored, software_version=software_version())
    try:
        for name, (_, values) in sampled.items():
            writer.append_channel(
                name,
                {"raw": [np.zeros(n, np.int8)], "values": [values],
                 "flags": [np.zeros(n, np.uint8)]},
                [(0, n, 0, 0.0, 0.0, 0)],
                [],
            )
        if tach is not None:
            edges = np.flatnonzero(tach).astype(np.int64)
            writer.append_channel(
                TACH, {"edge_indices": [edges], "edge_times_s": [edges / fs_hz]},
                [(0, n, 0.0, 0, edges.size)], [],
            )
        if meta.drive:
            writer.append_drive(
                [(0.0, 0, meta.drive[q.frequency_hz], meta.drive[q.amplitude_m], 1, 0)]
            )
        writer.write_status(RecordingStatus(
            end_host_time_s=0.0, samples_written=n * len(sampled), samples_lost=0, flushes=1,
            closed=True, stop_reason="completed",
        ))
        writer.flush()
    finally:
        writer.close()


def _check_record_arguments(args: argparse.Namespace) -> None:
    """Refuse a record length, sample rate or transient that makes no sense or no file."""
    for name in ("duration", "fs"):
        value = getattr(args, name)
        if not (math.isfinite(value) and value > 0):
            raise CommandError(f"--{name} {value!r}: must be a positive number")
    if not (math.isfinite(args.skip) and args.skip >= 0):
        raise CommandError(f"--skip {args.skip!r}: must be >= 0")
    if args.duration * args.fs > MAX_SAMPLES:
        raise CommandError(
            f"--duration {args.duration} s at --fs {args.fs} Hz is "
            f"{args.duration * args.fs:.3g} samples; the limit is {MAX_SAMPLES:.0e}"
        )


def run(args: argparse.Namespace) -> int:
    """Build the model, simulate, apply the measurement model, write the record."""
    import numpy as np

    from analysis.exchange import ExchangeRecord, write_exchange
    from analysis.measurement import MeasurementModel, has_measurement_causes
    from analysis.model import table_displacement
    from analysis.output_paths import HDF5_SUFFIXES, check_outputs, check_suffix
    from analysis.packed import P, ParameterError
    from analysis.simulate import SimulationSettings, simulate

    suffix = check_suffix(args.out, (".csv", *HDF5_SUFFIXES),
                          "a simulated record (CSV or HDF5)").suffix.lower()
    if not args.out.parent.exists():
        raise CommandError(f"--out {args.out}: folder {args.out.parent} does not exist")
    outputs = [args.out] + ([args.out.with_suffix(".json")] if suffix == ".csv" else [])
    check_outputs(outputs, overwrite=args.overwrite)
    _check_record_arguments(args)
    model, experiment = build_model(
        args.case, args.experiment, parse_assignments(args.param), args.cause
    )
    try:
        measurement = MeasurementModel(args.noise_rad, args.quantization_rad, args.seed)
    except ParameterError as error:
        raise CommandError(str(error)) from None

    progress(
        f"simulating {experiment} ({(args.case and 'paper case ' + args.case) or 'custom'}) "
        f"for {args.skip:g} s + {args.duration:g} s ..."
    )
    started = time.perf_counter()
    try:
        result = simulate(
            model, args.theta0, args.omega0,
            settings=SimulationSettings(
                duration_s=args.duration, fs_hz=args.fs, skip_s=args.skip, poincare_phase=None,
                rtol=args.rtol, atol=args.rtol * 1e-2,
            ),
        )
    except ValueError as error:
        raise CommandError(str(error)) from None
    wall = time.perf_counter() - started
    if not result.ok:
        log.warning(
            "warning: the simulation stopped early (%s) at t = %.4g s; writing the %d samples "
            "before", result.status, result.final_state[0], result.t.size
        )
    if result.t.size < 2:
        raise CommandError(f"the simulation produced too few samples ({result.status})")

    spectrum = _lyapunov(model, args, result.record_start_s) if args.lyapunov else None
    time_s = np.arange(result.t.size) / args.fs  # = result.t - record start, without rounding
    angle = result.theta
    measured = not measurement.is_ideal or has_measurement_causes(model)
    if measured:
        angle = measurement.apply(result.t, result.theta, model)
    table = tach = None
    p = model.pack()
    if experiment_kind(experiment).driven:
        phase = p[P.OMEGA_DRIVE] * result.t + p[P.PHASE0]
        table = table_displacement(phase, p[P.A1], p[P.A2], p[P.PHI2])
        tach = _tach(result.t, p, args.fs)
    extra = {
        "rig": model.rig.as_dict(),
        "drive": {
            q.frequency_hz: model.drive.frequency_hz,
            q.amplitude_m: model.drive.amplitude_m,
            "phase_at_time_zero_rad": 0.0,
        },
        "barrier": model.barrier,
        "extensions": {k: dict(v) for k, v in model.extensions.items()},
        "paper_case": args.case,
        q.theta0_rad: args.theta0,
        q.theta_dot0_rad_s: args.omega0,
        "skip_s": result.record_start_s,
        "sample_rate_hz": args.fs,
        "rtol": args.rtol,
        "measurement": {
            "noise_std_rad": measurement.noise_std_rad,
            "quantization_rad": measurement.quantization_rad,
            "seed": measurement.seed,
            "applied": measured,
        },
        "status": result.status,
        "contacts": result.contacts.count,
    }
    if spectrum is not None:
        extra["lyapunov_spectrum"] = spectrum
    meta = _metadata(model, experiment, args, extra)
    if suffix == ".csv":
        record = ExchangeRecord(time_s, angle, meta, table_m=table, tach=tach)
        csv_path, json_path = write_exchange(args.out, record, overwrite=args.overwrite)
        written = f"{csv_path} + {json_path.name}"
    else:
        columns = {"angle_rad": angle, "table_m": table, "tach": tach}
        _write_recording(args.out, columns, meta, args.fs, args.overwrite)
        written = str(args.out)
    print(
        f"simulate: {result.t.size} samples, {result.contacts.count} contacts, "
        f"{wall:.3f} s wall, status {result.status} -> {written}"
    )
    if spectrum is not None:
        from analysis.dynamics.lyapunov import spectrum_text

        driven = experiment_kind(experiment).driven
        print(spectrum_text(spectrum, "drive period" if driven else "natural period"))
    return 0 if result.ok else 1


def _lyapunov(model: Any, args: argparse.Namespace, transient_s: float) -> dict[str, Any]:
    """The model's Lyapunov spectrum from the run's start, over the recorded span after
    ``transient_s`` (:func:`analysis.dynamics.lyapunov.spectrum_report`)."""
    from analysis.dynamics.lyapunov import (
        SpectrumSettings,
        model_lyapunov_spectrum,
        spectrum_report,
    )

    try:
        spectrum = model_lyapunov_spectrum(
            model.pack(), args.theta0, args.omega0,
            SpectrumSettings(duration_s=args.duration, transient_s=transient_s,
                             rtol=args.rtol, atol=args.rtol * 1e-2),
        )
    except (ValueError, RuntimeError) as error:
        raise CommandError(f"--lyapunov: {error}") from None
    return spectrum_report(spectrum)


def _tach(t: Any, p: Any, fs_hz: float) -> Any:
    """1 on the sample nearest each instant of drive phase 0 (Omega t + phase0 = 2 pi k)."""
    import numpy as np

    from analysis.packed import P

    omega = p[P.OMEGA_DRIVE]
    tach = np.zeros(t.size, dtype=np.int64)
    k_first = math.ceil((omega * (t[0] - 0.5 / fs_hz) + p[P.PHASE0]) / (2 * math.pi))
    k_last = math.floor((omega * (t[-1] + 0.5 / fs_hz) + p[P.PHASE0]) / (2 * math.pi))
    instants = (2 * math.pi * np.arange(k_first, k_last + 1) - p[P.PHASE0]) / omega
    index = np.rint((instants - t[0]) * fs_hz).astype(np.int64)
    tach[index[(index >= 0) & (index < t.size)]] = 1
    return tach
