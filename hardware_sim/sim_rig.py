"""The whole virtual rig on real protocols: DAQ board on a pty; the shaker's drive on Modbus TCP
(and RTU), or a SCPI function generator on a TCP socket.

One :class:`VirtualRig` feeds the DAQ emulator and is moved by the drive's emulator: the
amplifier's Modbus controller (``drive="modbus"``) or a function generator feeding an
amplifier of gain ``gain_m_per_v`` (``drive="scpi"``).  While no host streams from the
DAQ board, a world clock keeps the physics running in (scaled) real time, so the shaker
still ramps and a watchdog still stops the table when a host goes away.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

from drivers.amplifier_registers import Fault
from hardware_sim.amplifier_emulator import AmplifierEmulator, TransportFault
from hardware_sim.amplifier_firmware import AmplifierFirmware
from hardware_sim.daq_emulator import DaqEmulator
from hardware_sim.scpi_generator import GeneratorState, ScpiGeneratorEmulator
from hardware_sim.virtual_rig import VirtualRig, VirtualRigSettings, compile_physics

WORLD_TICK_S = 0.02
DRIVES = ("modbus", "scpi")
# The host ramps a generator's amplitude itself; the emulated amplifier then follows each
# step with its mechanical lag only, not with a slew limit of its own.
GENERATOR_FOLLOW_RATE_M_S = 1.0


@dataclass(frozen=True)
class Endpoints:
    """Where the rig's devices can be reached."""

    daq_port: str | None  # pty path of the DAQ board, None when not started
    modbus_tcp: str | None  # host:port
    modbus_rtu: str | None  # pty path of the amplifier's RTU line
    scpi: str | None = None  # VISA resource of the function generator


class SimRig:
    """The virtual rig's devices, started together and stopped together."""

    def __init__(
        self,
        settings: VirtualRigSettings | None = None,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        tcp: bool = True,
        rtu: bool = False,
        daq: bool = True,
        drive: str = "modbus",
        gain_m_per_v: float = 1e-3,
        scpi_port: int = 0,
    ) -> None:
        if drive not in DRIVES:
            raise ValueError(f"drive = {drive!r}: expected one of {', '.join(DRIVES)}")
        if not (math.isfinite(gain_m_per_v) and gain_m_per_v > 0):
            raise ValueError(f"gain_m_per_v = {gain_m_per_v!r}: expected a number > 0")
        self.rig = VirtualRig(settings)
        self.drive = drive
        self.gain_m_per_v = float(gain_m_per_v)
        self.firmware = AmplifierFirmware(self.rig.shaker, plant_clock=None)
        self.amplifier = AmplifierEmulator(self.firmware, host=host, port=port, tcp=tcp, rtu=rtu)
        self.generator = ScpiGeneratorEmulator(
            host=host, port=scpi_port, on_change=self._generator_changed
        )
        self.daq = DaqEmulator(self.rig, speed=self.rig.speed_factor) if daq else None
        self._stop = threading.Event()
        self._clock: threading.Thread | None = None

    def start(self) -> SimRig:
        """Compile the physics, then start every device and the world clock.

        If one device cannot start, those already started are stopped again.
        """
        compile_physics(self.rig.settings)
        try:
            if self.drive == "scpi":
                self.generator.start()
            else:
                self.amplifier.start()
            if self.daq is not None:
                self.daq.start()
        except BaseException:
            self.stop()
            raise
        self._stop.clear()
        self._clock = threading.Thread(target=self._world_clock, name="world-clock", daemon=True)
        self._clock.start()
        return self

    def stop(self) -> None:
        """Stop the world clock and every device; safe to call twice."""
        self._stop.set()
        if self._clock is not None:
            self._clock.join(5.0)
            self._clock = None
        if self.daq is not None:
            self.daq.close()
        self.amplifier.stop()
        self.generator.stop()

    def __enter__(self) -> SimRig:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    @property
    def endpoints(self) -> Endpoints:
        """Paths and addresses to give the host software."""
        return Endpoints(
            daq_port=self.daq.port if self.daq is not None else None,
            modbus_tcp=self.amplifier.endpoint if self.amplifier.port is not None else None,
            modbus_rtu=self.amplifier.rtu_path,
            scpi=self.generator.resource if self.generator.port is not None else None,
        )

    def set_transport_fault(self, fault: TransportFault) -> None:
        """Switch the amplifier's communication fault (NONE to heal)."""
        self.amplifier.fault = fault

    def trip(self, fault: Fault) -> None:
        """Latch a hardware fault in the amplifier (over-current, over-temperature ...)."""
        self.firmware.trip(fault)

    def replug_daq(self, away_s: float = 0.0) -> str:
        """The DAQ board unplugged and plugged in again (a knocked cable, a board reset).

        The board's pty closes; after ``away_s`` seconds (the rig's physics running on
        meanwhile) a fresh board, its sample counter at 0 again, serves a new pty, whose
        path is returned.  No-op returning "" when no board was started.
        """
        if self.daq is None:
            return ""
        self.daq.close()
        if away_s > 0:
            time.sleep(away_s)
        self.daq = DaqEmulator(self.rig, speed=self.rig.speed_factor).start()
        return self.daq.port

    def restart_amplifier(self, away_s: float = 0.0) -> None:
        """The amplifier's controller restarted: its Modbus server goes away (every
        connection dropped) and, after ``away_s`` seconds, serves again on the same
        address.  Its firmware (setpoints, watchdog, the table it moves) carries on."""
        old = self.amplifier
        old.stop()
        if away_s > 0:
            time.sleep(away_s)
        self.amplifier = AmplifierEmulator(
            self.firmware, host=old.host, port=old.port or 0, tcp=True, rtu=False
        ).start()
        self.amplifier.fault = old.fault

    def _generator_changed(self, state: GeneratorState) -> None:
        """The generator's output through the amplifier (gain) moves the table."""
        vpp = state.amplitude_vpp * (2.0 * math.sqrt(2.0) if state.unit == "VRMS" else 1.0)
        if state.output:
            self.rig.shaker.set_targets(
                amplitude_m=vpp / 2.0 * self.gain_m_per_v,
                frequency_hz=state.frequency_hz,
                ramp_rate_m_s=GENERATOR_FOLLOW_RATE_M_S,
            )
        else:  # the frequency a silent generator holds does not move the table
            self.rig.shaker.set_targets(amplitude_m=0.0, ramp_rate_m_s=GENERATOR_FOLLOW_RATE_M_S)

    def _daq_streaming(self) -> bool:
        # an unplugged board (emulator closed) no longer moves time, whatever it last said
        return self.daq is not None and self.daq.serving and self.daq.firmware.streaming

    def _world_clock(self) -> None:
        last = time.monotonic()
        owed_s = 0.0  # stream time due but not yet generated (less than one sample)
        while not self._stop.wait(WORLD_TICK_S):
            now = time.monotonic()
            if self._daq_streaming():  # a streaming board moves time itself
                owed_s = 0.0
            else:
                owed_s += (now - last) * self.rig.speed_factor
                owed_s -= self.rig.advance(owed_s)
            last = now
