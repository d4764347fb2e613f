"""Open the rig's devices from a rig configuration: the real ports, or the virtual rig's emulators.

Either way the same drivers are used (serial DAQ board with its role drivers, and the
shaker the rig file names: the amplifier's Modbus controller or a SCPI function
generator): with a virtual rig, the emulators are started in this process on a pty
and loopback TCP ports, and the drivers connect to them over those real transports.
The one difference a procedure sees is ``release``: on the virtual rig it lets the
simulated pendulum go; on a real rig it asks the operator to do it.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

from drivers.daq import DaqBoard
from drivers.interfaces import DeviceError, InputStream
from drivers.modbus_shaker import ModbusRtuBackend, ModbusTcpBackend
from drivers.scpi_shaker import ScpiLink, ScpiShaker
from drivers.sensors import LaserDisplacementSensor, PotentiometerAngleSensor, Tachometer
from drivers.serial_daq import SerialDaqBackend
from drivers.shaker import ShakerAmplifier
from rig.config import RigConfig
from rig.recorder import ChannelSpec

ANGLE, TABLE, TACH = "angle", "table", "tach"

# The shaker's drive: both have the same settings, readings, limits and safe stop.
Shaker = ShakerAmplifier | ScpiShaker


@dataclass
class RigDevices:
    """The open devices of one rig; ``close()`` stops the drive first, then everything else."""

    config: RigConfig
    board: DaqBoard
    angle: PotentiometerAngleSensor
    table: LaserDisplacementSensor
    tach: Tachometer
    shaker: Shaker
    sim: object | None = None  # hardware_sim.sim_rig.SimRig when the rig is virtual
    ask_operator: Callable[[str], None] = field(default=lambda text: input(text))

    @property
    def streams(self) -> list[InputStream]:
        """The input streams the acquisition engine runs."""
        return [self.angle, self.table, self.tach]

    @property
    def sample_rate_hz(self) -> float:
        """The rate the board really samples at."""
        return self.board.sample_rate_hz

    def channel_specs(self) -> list[ChannelSpec]:
        """What the recorder must be set up for."""
        fs = self.sample_rate_hz
        calibrations = self.config.calibrations()
        daq = self._board_name()
        return [
            ChannelSpec(ANGLE, "samples", "rad", fs, daq, calibrations[ANGLE], "int16"),
            ChannelSpec(TABLE, "samples", "m", fs, daq, calibrations[TABLE], "int16"),
            ChannelSpec(TACH, "pulses", "", fs, daq, calibrations[TACH]),
        ]

    def identities(self) -> dict[str, dict[str, object]]:
        """Device identities for a recording's metadata."""
        out: dict[str, dict[str, object]] = {}
        if self.board.identity is not None:
            ident = self.board.identity
            out["daq"] = {
                "where": self.board.backend.description,
                "model": ident.model,
                "serial": ident.serial,
                "firmware": ident.firmware,
                "adc_bits": ident.adc_bits,
                "range_v": ident.range_v,
                "sample_rate_hz": self.sample_rate_hz,
            }
        if self.shaker.identity is not None:
            out["shaker"] = {
                "where": self.shaker.backend.description,
                "kind": self.config.shaker.kind,
                **asdict(self.shaker.identity),
            }
        out["rig"] = {"name": self.config.name, "kind": self.config.kind}
        return out

    def _board_name(self) -> str:
        ident = self.board.identity
        return f"{ident.model} {ident.serial}" if ident is not None else "DAQ board"

    # -- what needs a hand on a real rig ------------------------------------------------------

    def hold(self, theta0_rad: float) -> None:
        """Hold the pendulum still at ``theta0_rad`` (the simulated hand, or the operator's)."""
        if self.sim is not None:
            self.sim.rig.hold(theta0_rad)
        else:
            self.ask_operator(
                f"Hold the pendulum still at {math.degrees(theta0_rad):.1f} degrees, press "
                "Enter, then let go when you are ready (recording starts when it moves) ... "
            )

    def release(self, theta0_rad: float) -> None:
        """Let the pendulum go: the simulated hand does it now; on a real rig the operator
        lets go when ready (the procedure's trigger sees the motion)."""
        if self.sim is not None:
            self.sim.rig.release(theta0_rad)

    def set_barrier(self, present: bool) -> None:
        """Put the barrier in or take it out (simulated; an operator on a real rig)."""
        if self.sim is not None:
            self.sim.rig.set_barrier(present)
        else:
            state = "in place" if present else "removed"
            self.ask_operator(f"Make sure the barrier is {state}, then press Enter ... ")

    def close(self) -> None:
        """Drive to zero and release every device (safe after a failure, and twice).

        Whatever one device raises, the others are still released (the virtual rig's
        threads, pty and port included); the first unexpected error then propagates.
        """
        try:
            with contextlib.suppress(DeviceError):
                self.shaker.close()
        finally:
            try:
                with contextlib.suppress(DeviceError):
                    self.board.close()
            finally:
                sim, self.sim = self.sim, None
                if sim is not None:
                    sim.stop()

    def __enter__(self) -> RigDevices:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def open_rig(
    config: RigConfig,
    *,
    sample_rate_hz: float | None = None,
    virtual_speed: float = 1.0,
) -> RigDevices:
    """Open the devices the configuration names (starting the virtual rig when it is virtual).

    ``sample_rate_hz`` overrides the file's DAQ rate; ``virtual_speed`` runs the
    virtual rig faster than real time (tests).
    """
    fs = float(sample_rate_hz or config.daq.sample_rate_hz)
    sim = None
    daq_port = config.daq.port
    if config.is_virtual:
        sim = _start_virtual_rig(config, fs, virtual_speed)
        daq_port = sim.endpoints.daq_port
    board = None
    shaker = None
    try:
        board = DaqBoard(
            SerialDaqBackend(daq_port, baudrate=config.daq.baudrate),
            sample_rate_hz=fs,
            analog_channels=(config.daq.angle_input, config.daq.table_input),
            reconnect_for_s=config.daq.reconnect_for_s,
        )
        board.open()
        angle = PotentiometerAngleSensor(board, config.daq.angle_input, config.angle_calibration)
        table = LaserDisplacementSensor(board, config.daq.table_input, config.table_calibration)
        tach = Tachometer(board, config.tach_calibration)
        shaker = open_shaker(config, sim)
    except BaseException:
        if shaker is not None:
            with contextlib.suppress(DeviceError):
                shaker.close()
        if board is not None:
            with contextlib.suppress(DeviceError):
                board.close()
        if sim is not None:
            sim.stop()
        raise
    return RigDevices(config, board, angle, table, tach, shaker, sim)


def open_shaker(config: RigConfig, sim: Any = None) -> Shaker:
    """The shaker drive the rig file names (``shaker.kind``), connected.

    ``"modbus"``: the amplifier's controller on Modbus TCP or RTU; ``"scpi"``: a function
    generator through pyvisa, amplitudes converted with ``shaker.gain_m_per_v``.  With
    ``sim`` (a running virtual rig) the drive is the virtual rig's emulator of that kind.
    Both refuse settings outside ``[limits]`` before anything is sent.
    """
    s = config.shaker
    if s.kind == "scpi":
        resource = sim.generator.resource if sim is not None else s.resource
        shaker: Shaker = ScpiShaker(
            ScpiLink(resource, timeout_s=s.timeout_s),
            config.limits,
            gain_m_per_v=s.gain_m_per_v,
            max_output_vpp=s.max_output_vpp,
            channel=s.channel,
        )
    else:
        if sim is not None:
            backend = ModbusTcpBackend("127.0.0.1", sim.amplifier.port, device_id=s.unit_id)
        elif s.transport == "rtu":
            backend = ModbusRtuBackend(s.serial_port, device_id=s.unit_id)
        else:
            backend = ModbusTcpBackend(s.host, s.port, device_id=s.unit_id)
        shaker = ShakerAmplifier(
            backend, config.limits, watchdog_s=config.watchdog_s, reconnect=True
        )
    shaker.connect()
    return shaker


def _start_virtual_rig(config: RigConfig, sample_rate_hz: float, speed: float):
    """The virtual rig's emulators, with sensors that match the file's calibrations."""
    from analysis.model import Model, RigParameters
    from hardware_sim.sim_rig import SimRig
    from hardware_sim.virtual_rig import LaserOutput, PotentiometerOutput, VirtualRigSettings

    constants = config.constants
    pot, laser = config.angle_calibration, config.table_calibration
    if laser.unit != "V":
        raise DeviceError(
            f"{config.source}: the virtual rig's laser has an analog output; set "
            'calibration.table.unit = "V"'
        )
    model = Model(
        rig=RigParameters(
            m_kg=constants.m_kg,
            l_m=constants.l_m,
            L_m=constants.L_m,
            R_m=constants.R_m,
            g_m_s2=constants.g_m_s2,
            theta_b_rad=config.virtual.theta_b_rad,
        ),
        barrier=config.virtual.barrier,
    )
    for name, values in config.virtual.causes.items():  # effects the baseline model lacks
        model = model.with_extension(name, **values)
    settings = VirtualRigSettings(
        model=model,
        sample_rate_hz=sample_rate_hz,
        potentiometer=PotentiometerOutput(
            offset_v=pot.offset_v, gain_v_per_rad=1.0 / pot.gain_rad_per_v
        ),
        laser=LaserOutput(
            offset_v=-laser.zero_m / laser.m_per_unit, volts_per_m=1.0 / laser.m_per_unit
        ),
        angle_noise_rad=config.virtual.noise_rad,
        seed=config.virtual.seed,
        speed_factor=speed,
    )
    # SimRig.start compiles the physics before its emulators serve (no stalled first frames)
    drive = config.shaker
    gain = drive.gain_m_per_v if drive.kind == "scpi" else 1e-3
    return SimRig(settings, drive=drive.kind, gain_m_per_v=gain).start()


def virtual_config(config: RigConfig) -> RigConfig:
    """The same configuration, run on the virtual rig (``--sim``)."""
    return replace(config, kind="virtual")
