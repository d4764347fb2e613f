"""A model driven over the top in a sweep's diagram simulation: the step it went over on
and the steps after it are judged 'over-the-top' (no samples, the reason said), the steps
before keep their regime, and the comparison is made rather than abandoned."""

from __future__ import annotations

from analysis.model import Drive, Model, RigParameters
from analysis.sweep.diagram import StepPlan, SweepTask, model_fields, run_sweep_task


def test_steps_from_the_one_over_the_top_on_say_so() -> None:
    model = Model(rig=RigParameters(), drive=Drive(0.002, 5.0), barrier=False)
    plans = tuple(StepPlan(k, Drive(amplitude, 5.0), 500, 1500, 500.0, 1e-3)
                  for k, amplitude in enumerate((0.002, 0.5, 0.002)))
    simulated, judged = run_sweep_task(SweepTask(model_fields(model), plans))
    assert judged[0].short != "over-the-top" and simulated[0].theta_rad.size == 1500
    assert [j.short for j in judged[1:]] == ["over-the-top", "over-the-top"]
    assert all(s.theta_rad.size == 0 for s in simulated[1:])
    assert judged[2].label.startswith("the model's simulation stopped on step 1 (over")
