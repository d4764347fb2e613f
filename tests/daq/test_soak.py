"""The soak run on seconds: a recording from the virtual rig over its real wire protocols
(the board on a pty through a stable path, the amplifier on Modbus TCP, in their own
process) with each fault once: garbled frames, the board unplugged and plugged in again,
the amplifier's controller restarted.  ``benchmarks/soak.py`` runs it for an hour and
holds the memory figure to its goal; here every other quantity it prints is checked."""

from __future__ import annotations

import pytest

from harness.soak import FAULT_KINDS, GARBLED_FRAMES, run_soak


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_a_recording_with_every_fault_loses_only_the_fault_windows_and_reads_after(tmp_path):
    figures = run_soak(tmp_path, 12.0, fault_every_s=3.0, rate_hz=20_000.0, warmup_s=2.0)

    assert [kind for _, kind in figures.faults] == list(FAULT_KINDS)
    # nothing lost but what the faults cost, and each fault's window is in the file
    assert figures.samples_lost > 0 and figures.samples_lost_outside_fault_windows == 0
    assert figures.lost_outside_by_board_log == {}
    assert figures.injected_windows == figures.injected_windows_in_file == GARBLED_FRAMES
    assert figures.unplugs == figures.outages_in_file == 1
    assert figures.gaps_table_matches_blocks
    assert figures.duplicated_samples == 0
    # the amplifier's restart: seen (a drive-off row in the file), reached again, driven
    assert figures.amplifier_restarts == len(figures.amplifier_windows) == 1
    assert figures.drive_off_rows_in_file == 1
    # read while written (from another process) and after (reader, h5py, export)
    assert figures.live_reads_ok >= 1 and not figures.live_reads_failed
    assert figures.reader_ok and figures.h5py_ok and figures.export_ok, figures.export_message
    assert figures.samples_stored > 100_000
    assert figures.rss_warm_mb > 0 and figures.rss_end_mb > 0  # its goal: the benchmark's
