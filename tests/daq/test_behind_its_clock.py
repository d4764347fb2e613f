"""A simulated board whose simulation falls behind its sample clock (a loaded PC) streams on
a few frames at a time: one pass of its service loop produces at most FRAMES_PER_PASS of the
frames due, which are then written, instead of computing everything due before writing any
(under load the demo's virtual board fell silent for over 15 s, its driver called it
stalled and the sweep stopped)."""

from __future__ import annotations

from hardware_sim.daq_emulator import FRAMES_PER_PASS, DaqEmulator
from hardware_sim.daq_firmware import DaqFirmware
from hardware_sim.sample_source import CounterSource


def test_a_board_far_behind_its_clock_produces_a_few_frames_per_pass():
    now = [0.0]
    emulator = DaqEmulator(CounterSource(), speed=1.0)
    emulator.firmware = firmware = DaqFirmware(CounterSource(), speed=1.0,
                                               clock=lambda: now[0])
    assert firmware.handle("START").startswith("OK")
    now[0] = 60.0  # a minute on the board's clock, none simulated: thousands of frames due
    due = firmware.frames_due()
    assert due > 100 * FRAMES_PER_PASS
    emulator._produce_due_frames()
    assert emulator.frames_sent == FRAMES_PER_PASS
    emulator._produce_due_frames()
    assert emulator.frames_sent == 2 * FRAMES_PER_PASS
    assert firmware.frames_due() >= due - 2 * FRAMES_PER_PASS  # nothing skipped, nothing lost
    assert not emulator.faults.log
