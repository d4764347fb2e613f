"""``impact-rig sim-rig``: run the virtual rig on real protocols until Ctrl-C.

Prints one ``name: endpoint`` line per device (DAQ pty, Modbus TCP address, RTU
pty; or the SCPI generator's VISA resource with ``--drive scpi``), then serves.
Lines typed on stdin act on the rig while it runs (``help`` lists them), so a person
or a test can release the pendulum or inject faults.
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
from typing import Any

from rig.cli import CommandError

CAUSE_HELP = """\
causes (docs/MODEL.md section 6) are switched on with --cause NAME, each followed by
its parameters as --param NAME=VALUE, e.g.
  impact-rig sim-rig --cause coulomb_friction --param Tc_N_m=2e-4 --cause sensor_offset \\
      --param offset_rad=0.01

commands read from stdin while running:
  release RAD          the operator lets go of the pendulum at RAD
  hold RAD             the operator holds the pendulum at RAD
  barrier in|out       put the barrier in or take it out
  fault NAME           amplifier link fault: none, no_reply, device_failure, busy;
                       with --drive scpi the generator's: none, no_answer, queue_error,
                       clip_amplitude, ignore_frequency
  trip NAME            latch an amplifier fault: over_amplitude, over_current,
                       over_temperature, interlock_open (Modbus drive only)
  interlock open|closed  (Modbus drive only)
  status               print time, angle, table output and faults
"""


class _CauseAction(argparse.Action):
    """--cause NAME starts a cause; --param NAME=VALUE adds to the last one (order matters)."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        value: Any,
        option: str | None = None,
    ) -> None:
        causes: list[tuple[str, dict[str, float]]] = getattr(namespace, "causes", None) or []
        if option == "--cause":
            causes.append((value, {}))
        else:
            if not causes:
                parser.error(f"--param {value}: give --cause NAME before its parameters")
            name, _, text = value.partition("=")
            try:
                number = float(text)
            except ValueError:
                parser.error(f"--param {value}: expected NAME=NUMBER, e.g. Tc_N_m=2e-4")
            causes[-1][1][name.strip()] = number
        namespace.causes = causes


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``sim-rig`` sub-command."""
    parser = subparsers.add_parser(
        "sim-rig",
        help="start the virtual rig on real protocols (pty serial DAQ + Modbus amplifier)",
        description=(
            "Start the virtual impact-pendulum rig: the DAQ board on a pseudo-terminal and "
            "the shaker amplifier on Modbus TCP (127.0.0.1 unless --host says otherwise), "
            "optionally Modbus RTU on a pseudo-terminal; or, with --drive scpi, a function "
            "generator serving SCPI on a TCP socket in place of the Modbus controller "
            "(docs/scpi_generator.md).  Prints the endpoints, then runs until Ctrl-C."
        ),
        epilog=CAUSE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        help="address the Modbus TCP server binds (default: loopback only)",
    )
    parser.add_argument(
        "--port", type=int, default=5020, help="Modbus TCP port (default 5020; 0 = any free port)"
    )
    parser.add_argument("--rtu", action="store_true", help="also serve Modbus RTU on a pty")
    parser.add_argument(
        "--drive",
        choices=["modbus", "scpi"],
        default="modbus",
        help="the shaker's drive: the amplifier's Modbus controller (default) or a SCPI "
        "function generator feeding the amplifier",
    )
    parser.add_argument(
        "--scpi-port",
        type=int,
        default=5025,
        help="TCP port of the SCPI generator with --drive scpi (default 5025; 0 = any free port)",
    )
    parser.add_argument(
        "--gain",
        type=float,
        default=1e-3,
        metavar="M_PER_V",
        help="with --drive scpi: the emulated amplifier's gain, table amplitude in m per volt "
        "of generator amplitude (default 1e-3; a rig file's shaker.gain_m_per_v must match)",
    )
    parser.add_argument("--no-daq", action="store_true", help="do not start the DAQ board")
    parser.add_argument(
        "--speed",
        type=float,
        default=1.0,
        help="clock speed factor: 10 runs ten times faster than real time",
    )
    parser.add_argument(
        "--theta0", type=float, default=0.0, metavar="RAD", help="initial pendulum angle (rad)"
    )
    parser.add_argument("--no-barrier", action="store_true", help="start with the barrier out")
    parser.add_argument(
        "--angle-noise",
        type=float,
        default=2e-4,
        metavar="RAD",
        help="angle sensor noise, standard deviation (rad)",
    )
    parser.add_argument(
        "--table-noise",
        type=float,
        default=2e-6,
        metavar="M",
        help="laser noise, standard deviation (m)",
    )
    parser.add_argument("--seed", type=int, default=1, help="noise seed")
    parser.add_argument(
        "--cause", action=_CauseAction, metavar="NAME", help="switch on a named cause (repeatable)"
    )
    parser.add_argument(
        "--param",
        action=_CauseAction,
        metavar="NAME=VALUE",
        help="parameter of the preceding --cause",
    )
    parser.add_argument(
        "--fault",
        default="none",
        choices=["none", "no_reply", "device_failure", "busy"],
        help="amplifier communication fault at start (Modbus drive)",
    )
    parser.set_defaults(func=run, causes=[])


def _build(args: argparse.Namespace) -> Any:
    from analysis.model import Model
    from analysis.packed import ParameterError
    from hardware_sim.amplifier_emulator import TransportFault
    from hardware_sim.sim_rig import SimRig
    from hardware_sim.virtual_rig import VirtualRigSettings

    if not (math.isfinite(args.speed) and args.speed > 0):
        raise CommandError(f"--speed {args.speed}: expected a positive number")
    if not 0 <= args.port <= 65535:
        raise CommandError(f"--port {args.port}: expected 0..65535")
    if not 0 <= args.scpi_port <= 65535:
        raise CommandError(f"--scpi-port {args.scpi_port}: expected 0..65535")
    if not (math.isfinite(args.gain) and args.gain > 0):
        raise CommandError(f"--gain {args.gain}: expected a positive number (m per V)")
    try:
        model = Model(barrier=not args.no_barrier)
        for name, values in args.causes:
            model = model.with_extension(name, **values)
        settings = VirtualRigSettings(
            model=model,
            theta0_rad=args.theta0,
            speed_factor=args.speed,
            angle_noise_rad=args.angle_noise,
            table_noise_m=args.table_noise,
            seed=args.seed,
        )
    except (ParameterError, ValueError) as error:
        raise CommandError(str(error)) from None
    sim = SimRig(
        settings,
        host=args.host,
        port=args.port,
        rtu=args.rtu,
        daq=not args.no_daq,
        drive=args.drive,
        gain_m_per_v=args.gain,
        scpi_port=args.scpi_port,
    )
    sim.set_transport_fault(TransportFault(args.fault))
    return sim


def run(args: argparse.Namespace) -> int:
    """Start, print the endpoints, serve until Ctrl-C (or end of stdin commands: keep serving)."""
    sim = _build(args)
    try:
        sim.start()
    except (OSError, RuntimeError) as error:
        scpi = args.drive == "scpi"
        port, option = (args.scpi_port, "--scpi-port") if scpi else (args.port, "--port")
        raise CommandError(
            f"could not start the virtual rig on {args.host}:{port}: {error} "
            f"(port in use? try {option} 0)"
        ) from None
    ends = sim.endpoints
    stopped = threading.Event()
    try:  # Ctrl-C from here on, even right after 'ready', stops the rig cleanly
        print(f"impact-rig sim-rig: virtual rig running at {args.speed:g}x real time", flush=True)
        if ends.daq_port:
            print(f"daq-serial: {ends.daq_port}")
        else:
            print("daq-serial: not started")
        if ends.scpi:
            print(f"scpi-generator: {ends.scpi}  (gain {args.gain:g} m/V)")
            print(
                "note: this emulated generator turns its output off when the host's connection "
                "drops; a real one does not (docs/scpi_generator.md)"
            )
        else:
            print(f"modbus-tcp: {ends.modbus_tcp}")
        if ends.modbus_rtu:
            print(f"modbus-rtu: {ends.modbus_rtu}")
        print("ready; Ctrl-C stops (type 'help' for commands)", flush=True)
        reader = threading.Thread(target=_read_commands, args=(sim, stopped), daemon=True)
        reader.start()
        while not stopped.wait(0.2):
            pass
    except KeyboardInterrupt:
        pass
    finally:
        sim.stop()
    print("impact-rig sim-rig: stopped", flush=True)
    return 0


def _read_commands(sim: Any, stopped: threading.Event) -> None:
    """Act on stdin lines until stdin closes (then keep serving until Ctrl-C)."""
    for line in sys.stdin:
        try:
            reply = _command(sim, line.split())
        except ValueError as error:
            reply = f"error: {error}"
        if reply:
            print(reply, flush=True)


def _command(sim: Any, words: list[str]) -> str:
    from drivers.amplifier_registers import Fault
    from hardware_sim.amplifier_emulator import TransportFault
    from hardware_sim.scpi_generator import GeneratorFault

    if not words:
        return ""
    verb, rest = words[0].lower(), words[1:]
    if verb == "help":
        return CAUSE_HELP.split("commands read from stdin while running:\n", 1)[1].rstrip()
    if verb in ("release", "hold") and len(rest) == 1:
        angle = float(rest[0])
        if not math.isfinite(angle):
            raise ValueError(f"{verb} {rest[0]}: expected a finite angle in rad")
        (sim.rig.release if verb == "release" else sim.rig.hold)(angle)
        return f"ok {verb} {angle:g} rad"
    if verb == "barrier" and rest in (["in"], ["out"]):
        sim.rig.set_barrier(rest[0] == "in")
        return f"ok barrier {rest[0]}"
    scpi = getattr(sim, "drive", "modbus") == "scpi"  # sim is None while words are checked
    if verb == "fault" and len(rest) == 1 and scpi:
        generator_faults = {f.value: f for f in GeneratorFault}
        if rest[0] not in generator_faults:
            raise ValueError(f"fault {rest[0]!r}: expected one of {', '.join(generator_faults)}")
        sim.generator.fault = generator_faults[rest[0]]
        return f"ok fault {rest[0]}"
    if verb in ("trip", "interlock") and scpi:
        raise ValueError(f"{verb}: the SCPI generator has no {verb}; it is the Modbus drive's")
    if verb == "fault" and len(rest) == 1:
        faults = {f.value: f for f in TransportFault}
        if rest[0] not in faults:
            raise ValueError(f"fault {rest[0]!r}: expected one of {', '.join(faults)}")
        sim.set_transport_fault(faults[rest[0]])
        return f"ok fault {rest[0]}"
    if verb == "trip" and len(rest) == 1:
        trips = {f.name.lower(): f for f in Fault}
        if rest[0].lower() not in trips:
            raise ValueError(f"trip {rest[0]!r}: expected one of {', '.join(trips)}")
        sim.trip(trips[rest[0].lower()])
        return f"ok trip {rest[0]}"
    if verb == "interlock" and rest in (["open"], ["closed"]):
        sim.firmware.set_interlock(rest[0] == "open")
        return f"ok interlock {rest[0]}"
    if verb == "status" and not rest:
        t, theta, _ = sim.rig.state()
        out = sim.rig.table_output
        drive = (
            f"generator={sim.generator.state!r}"
            if sim.drive == "scpi"
            else f"faults={sim.firmware.faults!r}"
        )
        return (
            f"t={t:.3f} s theta={theta:.5f} rad table={out.amplitude_m:.6g} m "
            f"at {out.frequency_hz:.6g} Hz {drive}"
        )
    raise ValueError(f"unknown command {' '.join(words)!r} (type 'help')")
