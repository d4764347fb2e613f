"""The kinds of experiment a record can be: what each one is, what one record of it determines,
how the analysis judges models on it, and which named causes can show in it.

A kind is an object, so code asks what matters (is the barrier in? does the table move?)
instead of comparing names.  Whether a cause can show follows from what the cause needs
(``Cause.needs`` in :mod:`analysis.extensions`: the barrier, the drive, a response richer
than one damped sinusoid) and what the kind provides; the reason a kind gives for a need
it lacks is what the report says.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from analysis import quantities as q

BARRIER = "barrier"  # the pendulum strikes the barrier
DRIVE = "drive"  # the table moves
HARMONICS = "harmonics"  # the swing is more than one damped sinusoid (impacts, a drive)


@dataclass(frozen=True)
class ExperimentKind:
    """One kind of experiment (docs/MODEL.md section 5 names)."""

    name: str
    label: str  # for people
    provides: frozenset[str]  # of BARRIER, DRIVE, HARMONICS
    determines: tuple[str, ...]  # parameters one record determines (docs/MODEL.md section 7)
    comparison: str  # how the discrepancy analysis judges candidate models on it
    # why a cause needing what this kind lacks cannot show, by need
    lacks: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "lacks", MappingProxyType(dict(self.lacks)))

    @property
    def barrier(self) -> bool:
        """True when the barrier is in."""
        return BARRIER in self.provides

    @property
    def driven(self) -> bool:
        """True when the table moves."""
        return DRIVE in self.provides

    @property
    def shows_backbone(self) -> bool:
        """True when the swing is one damped sinusoid, so that the record shows its
        frequency against its amplitude (the backbone) cycle by cycle."""
        return HARMONICS not in self.provides

    def hidden_reason(self, needs: frozenset[str]) -> str | None:
        """Why a cause with these needs cannot show in this kind (None when it can)."""
        missing = sorted(needs - self.provides)
        return self.lacks[missing[0]] if missing else None


FREE_DECAY = ExperimentKind(
    name="free_decay",
    label="free decay",
    provides=frozenset(),
    determines=(q.L_m, q.omega_rad_s, q.zeta, q.theta0_rad, q.offset_rad),
    comparison="point by point: fitted on the first part, predicting the rest",
    lacks={
        BARRIER: "a free decay has no barrier, so a contact law or barrier position cannot show",
        DRIVE: "the table does not move in a decay, so the excitation cannot show",
        HARMONICS: "a damped sinusoid passed through a first-order lag is again a damped "
        "sinusoid: the lag only shifts its phase and scales it, which the initial state "
        "absorbs",
    },
)
IMPACT_DECAY = ExperimentKind(
    name="impact_decay",
    label="impact decay",
    provides=frozenset({BARRIER, HARMONICS}),
    determines=(q.L_m, q.omega_rad_s, q.zeta, q.K_N_per_m1_5, q.E_Pa, q.mu0_s_per_m,
                q.theta_b_rad, q.theta0_rad, q.offset_rad),
    comparison="point by point: fitted on the first part, predicting the rest",
    lacks={DRIVE: "the table does not move in a decay, so the excitation cannot show"},
)
FORCED = ExperimentKind(
    name="forced",
    label="forced response",
    provides=frozenset({BARRIER, DRIVE, HARMONICS}),
    determines=(q.L_m, q.omega_rad_s, q.zeta, q.K_N_per_m1_5, q.E_Pa, q.mu0_s_per_m,
                q.theta_b_rad, q.offset_rad, q.amplitude_m, q.frequency_hz),
    comparison="multiple shooting over the record; forecasts of the stretches after fitted "
    "ones (and, when chaotic, the invariant statistics of the model's own long run)",
)

KINDS: Mapping[str, ExperimentKind] = MappingProxyType(
    {kind.name: kind for kind in (FREE_DECAY, IMPACT_DECAY, FORCED)}
)
NAMES: tuple[str, ...] = tuple(KINDS)


def experiment_kind(name: str) -> ExperimentKind:
    """The kind called ``name``, with an error that lists the known ones."""
    try:
        return KINDS[name]
    except KeyError:
        raise ValueError(f"experiment {name!r}; expected one of {', '.join(NAMES)}") from None
