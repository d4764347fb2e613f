"""What the demo runs with: its settings (full and quick), the hidden cause, the folder
names of its report, and its error; the leaf every stage of the demo imports."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from analysis import quantities as q
from analysis.progress import ProgressText

NONE = "none"
DEFAULT_CAUSE = "coulomb_friction"
# Pivot friction that takes about 5 mrad off the swing per cycle: as much as the viscous
# damping does at 0.12 rad, so the free decay's envelope turns visibly straight, while
# a release at 0.15 rad still gives a decay of some twenty cycles.
DEFAULT_CAUSE_VALUES: Mapping[str, float] = MappingProxyType({q.Tc_N_m: 2.0e-5})
RECORDINGS = "recordings"
FIGURES = "figures"
ANALYSIS = "analysis"  # one discrepancy-analysis page (Markdown, JSON, figures) per record
REPORT_NAME = "report.md"


class DemoError(RuntimeError):
    """The demo cannot run or cannot go on; the message says what was wrong."""


@dataclass(frozen=True)
class HiddenCause:
    """The effect switched on in the virtual rig (``none``: the baseline model is exact)."""

    name: str
    values: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))

    def describe(self) -> str:
        """'coulomb_friction (Tc_N_m = 2e-05)' or 'none'."""
        if self.name == NONE:
            return NONE
        inner = ", ".join(f"{k} = {v:g}" for k, v in self.values.items())
        return f"{self.name} ({inner})"


def hidden_cause(name: str, given: Mapping[str, float] | None = None) -> HiddenCause:
    """Validate a cause name and its parameter values against the registry (defaults filled in)."""
    from analysis.extensions import cause
    from analysis.packed import ParameterError

    given = dict(given or {})
    if name == NONE:
        if given:
            raise DemoError(f"--cause none takes no parameters (got {sorted(given)})")
        return HiddenCause(NONE)
    try:
        values = cause(name).values(given)
    except ParameterError as error:
        raise DemoError(str(error)) from None
    return HiddenCause(name, MappingProxyType(values))


@dataclass(frozen=True)
class DemoSettings:
    """How much the demo records and simulates.  Durations are in rig time (the virtual
    rig runs ``virtual_speed`` times faster than the wall clock)."""

    name: str
    sample_rate_hz: float
    virtual_speed: float
    free_release_rad: float
    impact_release_rad: float
    decay_max_s: float
    decay_stop_below_rad: float
    sweep_frequency_hz: float
    sweep_betas: tuple[float, ...]
    settle_s: float
    dwell_s: float
    simulated_betas: int
    simulated_periods: int
    simulated_record_periods: int
    analyze_forced_step: bool  # the discrepancy analysis of a sweep step (slow)
    # check the impact decay and the sweep only for what the free decay found (when it
    # found something) instead of for every candidate: a shortcut of the quick demo
    carry_free_decay_finding: bool


FULL = DemoSettings(
    name="full",
    sample_rate_hz=4000.0,
    virtual_speed=5.0,
    free_release_rad=0.15,
    impact_release_rad=-0.3,
    decay_max_s=60.0,
    decay_stop_below_rad=0.005,
    sweep_frequency_hz=10.0,
    sweep_betas=(0.02, 0.035, 0.05, 0.065, 0.08, 0.095, 0.11, 0.125),
    settle_s=6.0,
    dwell_s=8.0,
    simulated_betas=80,
    simulated_periods=500,
    simulated_record_periods=100,
    analyze_forced_step=True,
    carry_free_decay_finding=False,
)

QUICK = DemoSettings(
    name="quick",
    sample_rate_hz=2000.0,
    virtual_speed=5.0,
    free_release_rad=0.15,
    impact_release_rad=-0.2,
    decay_max_s=30.0,
    decay_stop_below_rad=0.01,
    sweep_frequency_hz=10.0,
    sweep_betas=(0.03, 0.07, 0.11),
    settle_s=3.0,
    dwell_s=5.5,
    simulated_betas=12,
    simulated_periods=200,
    simulated_record_periods=40,
    analyze_forced_step=False,
    carry_free_decay_finding=True,
)


def indented(say: ProgressText) -> ProgressText:
    """Progress one level deeper (the steps of a stage)."""
    return lambda text: say(f"    {text}")

