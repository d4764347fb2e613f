"""The whole virtual rig on real protocols: DAQ board on a pty, amplifier on Modbus TCP (and RTU).

One :class:`VirtualRig` feeds the DAQ emulator and is moved by the amplifier
emulator.  While no host streams from the DAQ board, a world clock keeps the
physics running in (scaled) real time, so the shaker still ramps and the watchdog
still stops the table when a host goes away.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from drivers.amplifier_registers import Fault
from hardware_sim.amplifier_emulator import AmplifierEmulator, TransportFault
from hardware_sim.amplifier_firmware import AmplifierFirmware
from hardware_sim.daq_emulator import DaqEmulator
from hardware_sim.virtual_rig import VirtualRig, VirtualRigSettings, compile_physics

WORLD_TICK_S = 0.02


@dataclass(frozen=True)
class Endpoints:
    """Where the rig's devices can be reached."""

    daq_port: str | None  # pty path of the DAQ board, None when not started
    modbus_tcp: str | None  # host:port
    modbus_rtu: str | None  # pty path of the amplifier's RTU line


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
    ) -> None:
        self.rig = VirtualRig(settings)
        self.firmware = AmplifierFirmware(self.rig.shaker, plant_clock=None)
        self.amplifier = AmplifierEmulator(self.firmware, host=host, port=port, tcp=tcp, rtu=rtu)
        self.daq = DaqEmulator(self.rig, speed=self.rig.speed_factor) if daq else None
        self._stop = threading.Event()
        self._clock: threading.Thread | None = None

    def start(self) -> SimRig:
        """Compile the physics, then start every device and the world clock.

        If one device cannot start, those already started are stopped again.
        """
        compile_physics(self.rig.settings)
        try:
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
        )

    def set_transport_fault(self, fault: TransportFault) -> None:
        """Switch the amplifier's communication fault (NONE to heal)."""
        self.amplifier.fault = fault

    def trip(self, fault: Fault) -> None:
        """Latch a hardware fault in the amplifier (over-current, over-temperature ...)."""
        self.firmware.trip(fault)

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
