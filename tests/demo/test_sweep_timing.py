"""The demo's sweep on a virtual rig run faster than real time (as the demo runs it) keeps its
plan in the recording: each step's settle and dwell are counted on the samples (the rig's
own clock), not on the wall clock, so a loaded host that receives the samples in bursts, or a
virtual rig slower than its speed, still records every step with the planned settle and
dwell (a wall-clock dwell of the quick demo held 0 to 5 s of samples on a loaded machine,
and its sweep could not be explained); and the recording loads as a sweep whose every step
is kept, with its tach and table channel."""

from __future__ import annotations

import pytest

from analysis.sweep.load import load_sweep
from recording.reader import open_recording
from rig.config import load_config
from rig.demo.record import demo_config
from rig.demo.settings import NONE, HiddenCause
from rig.devices import open_rig
from rig.procedures import SweepPlan, run_sweep

FS_HZ = 1000.0
SPEED = 5.0  # the demo's


def test_every_step_holds_its_planned_settle_and_dwell_in_samples(tmp_path):
    config = demo_config(load_config(), HiddenCause(NONE))
    devices = open_rig(config, sample_rate_hz=FS_HZ, virtual_speed=SPEED)
    plan = SweepPlan("amplitude", (0.5e-3, 1.0e-3), 10.0, settle_s=0.5, dwell_s=2.5)
    try:
        result = run_sweep(devices, tmp_path / "sweep.h5", plan)
    finally:
        devices.close()
    with open_recording(result.path) as recording:
        steps = recording.sweep_steps()
    settle = steps["dwell_start_index"] - steps["settle_start_index"]
    dwell = steps["dwell_end_index"] - steps["dwell_start_index"]
    assert steps["complete"].tolist() == [1, 1, 1]
    assert settle.tolist() == [500, 500, 500]  # not 5 x as many: 0.5 s of the rig's time
    assert dwell.tolist() == [2500, 2500, 2500]
    assert all(steps["settle_start_index"][1:] >= steps["dwell_end_index"][:-1])
    sweep = load_sweep([result.path])
    assert [s.number for s in sweep.steps] == [0, 1, 2] and sweep.set_aside == ()
    assert [s.amplitude_m for s in sweep.steps] == [0.5e-3, 1.0e-3, 0.5e-3]
    for step in sweep.steps:
        assert step.settle_s == pytest.approx(0.5)
        assert step.record.tach_indices.size >= 20  # 10 Hz over 2.5 s
        assert step.record.table_m is not None and step.record.table_m.size == 2500
