"""The next experiment: forced steps where competing explanations' predicted records differ
most against the record's noise, beyond what their own parameter intervals can produce."""

from analysis.suggest.candidates import (
    Candidate,
    CompetingPair,
    ReportError,
    competing_pairs,
    report_rig,
    weak_finding,
)
from analysis.suggest.forced_steps import (
    PairSearch,
    Setting,
    Suggestion,
    run_setting,
    search,
    settings_grid,
)

__all__ = [
    "Candidate",
    "CompetingPair",
    "PairSearch",
    "ReportError",
    "Setting",
    "Suggestion",
    "competing_pairs",
    "report_rig",
    "run_setting",
    "search",
    "settings_grid",
    "weak_finding",
]
