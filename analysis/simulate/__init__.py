"""Fast, exact simulation of the impact pendulum: single runs, a streaming stepper, ensembles,
and the sensitivities of a run."""

from analysis.simulate.ensemble import EnsembleResult, simulate_ensemble
from analysis.simulate.result import ContactEvents, SimulationResult, StickEvents, Trajectory
from analysis.simulate.sensitivity import (
    Sensitivities,
    SensitivitySettings,
    simulate_sensitivities,
)
from analysis.simulate.simulation import (
    SimulationSettings,
    drive_period_s,
    poincare_times,
    record_start_s,
    simulate,
    simulate_packed,
)
from analysis.simulate.stepper import SimulationStoppedError, Stepper

__all__ = [
    "ContactEvents",
    "EnsembleResult",
    "Sensitivities",
    "SensitivitySettings",
    "SimulationResult",
    "SimulationSettings",
    "SimulationStoppedError",
    "Stepper",
    "StickEvents",
    "Trajectory",
    "drive_period_s",
    "poincare_times",
    "record_start_s",
    "simulate",
    "simulate_ensemble",
    "simulate_packed",
    "simulate_sensitivities",
]
