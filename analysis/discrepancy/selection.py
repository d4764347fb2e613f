"""Does an extension earn its keep?  Penalised fit quality and prediction of unseen data.

Two independent judges must agree.  The information criterion (BIC) weighs the
drop in the residual sum of squares, in units of the noise variance the data
show, against the extra parameters; residual autocorrelation is handled by
counting effective samples (n over the integrated correlation time), so that a
smooth leftover misfit is not mistaken for thousands of independent votes.  The
held-out test fits the first part of the record and predicts the rest, where a
parameter that only absorbs noise gains nothing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from analysis.discrepancy.fitting import FitResult
from analysis.discrepancy.policy import DEFAULT_POLICY, SelectionPolicy
from analysis.extensions import ModelSpec
from analysis.identify.intervals import correlation_time


def information_criterion_delta(
    baseline: FitResult, extended: FitResult, noise_rad: float
) -> float:
    """BIC(baseline) - BIC(extended) with effective samples; > 0 favours the extension."""
    n = max(extended.n, 1)
    sigma2 = max(noise_rad**2, extended.rss / n, 1e-300)
    tau = correlation_time(extended.residual)
    n_eff = max(n / tau, 2.0)
    chi2_gain = (baseline.rss - extended.rss) / (sigma2 * tau)
    extra = extended.n_params - baseline.n_params
    return float(chi2_gain - extra * math.log(n_eff))


@dataclass(frozen=True)
class Verdict:
    """Both judges' view of one candidate."""

    model: ModelSpec
    information_criterion_delta: float
    heldout_rms_baseline: float
    heldout_rms_extended: float
    rms_baseline: float
    rms_extended: float
    invariant_distance_baseline: float | None = None  # chaotic records: statistics, not points
    invariant_distance_extended: float | None = None
    noise_rad: float = 0.0
    n_heldout: int = 0
    # forced records: the drop of the mean-square forecast error, in its standard errors,
    # from the held-out stretches taken one by one (paired: both models see the same noise)
    forecast_z: float | None = None
    not_judged: str | None = None  # why the forecast judge was not run (a better cause won)
    # why the fitted values are no explanation a real rig can have (outside the cause's
    # plausible range, or on a bound of the fit): it then explains nothing, whatever it gains
    implausible: str | None = None
    policy: SelectionPolicy = field(default=DEFAULT_POLICY, repr=False, compare=False)

    @property
    def heldout_ratio(self) -> float:
        """Extended over baseline prediction error on the held-out part (< 1: better)."""
        if not (self.heldout_rms_baseline > 0):
            return math.inf
        return self.heldout_rms_extended / self.heldout_rms_baseline

    @property
    def heldout_excess_ratio(self) -> float:
        """Like ``heldout_ratio`` for the part of the prediction error above the noise."""
        s2 = self.noise_rad**2
        base = self.heldout_rms_baseline**2 - s2
        ext = max(self.heldout_rms_extended**2 - s2, 0.0)
        return math.sqrt(ext / base) if base > 0 else math.inf

    @property
    def heldout_helps(self) -> bool:
        """The held-out judge: a clearly smaller prediction error on the unseen part.

        Either the error drops to the policy's ``heldout_ratio``, or - when an effect is
        small against the noise - the drop is significant: on forced records, by a paired
        test over the held-out stretches (``forecast_z`` standard errors); on decays, whose
        one held-out part cannot be split so, when its excess over the noise drops to
        ``heldout_excess_ratio`` and the mean-square gain is well beyond the scatter a
        finite held-out sample allows
        (``heldout_sigmas`` standard errors of a noise variance).
        """
        rules = self.policy
        if self.heldout_ratio < rules.heldout_ratio:
            return True
        if self.forecast_z is not None:
            return self.forecast_z > rules.forecast_z
        if self.n_heldout <= 0 or not self.noise_rad > 0:
            return False
        gain = self.heldout_rms_baseline**2 - self.heldout_rms_extended**2
        scatter = self.noise_rad**2 * math.sqrt(2.0 / self.n_heldout)
        return gain > rules.heldout_sigmas * scatter \
            and self.heldout_excess_ratio < rules.heldout_excess_ratio

    @property
    def invariant_ratio(self) -> float | None:
        """Extended over baseline distance of the invariant statistics (chaotic records)."""
        if self.invariant_distance_baseline is None or self.invariant_distance_extended is None:
            return None
        if not self.invariant_distance_baseline > 0:
            return math.inf
        return self.invariant_distance_extended / self.invariant_distance_baseline

    @property
    def earns_keep(self) -> bool:
        """True when both judges say the extension helps by a clear margin.  On a chaotic
        record the invariant statistics join them: alone when there are no forecasts (a
        ratio under the policy's ``invariant_ratio``), or as a veto of forecasts whose
        model's long run is no closer to the record's statistics than the baseline's.  One
        long run's statistics
        are noisy (a right cause's run came 1.4 times further away than the baseline's on
        a record whose forecasts it improved threefold): the veto needs the run further
        away by more than the factor the forecasts gain."""
        rules = self.policy
        if self.information_criterion_delta <= rules.bic_margin or self.implausible:
            return False
        ratio = self.invariant_ratio
        if ratio is not None and self.forecast_z is None:
            return ratio < rules.invariant_ratio
        if ratio is not None and ratio >= max(1.0, 1.0 / self.heldout_ratio):
            return False  # forecasts better, but its own long run further from the record's
        return self.heldout_helps

    @property
    def earns_keep_but_implausible(self) -> bool:
        """True when the extension would earn its keep but its values are no real rig's: the
        record asks for something its named causes can only stand in for."""
        return self.implausible is not None and replace(self, implausible=None).earns_keep

    @property
    def why(self) -> str:
        """One line on the verdict."""
        if self.not_judged:
            return f"BIC gain {self.information_criterion_delta:.3g}; {self.not_judged}"
        if self.implausible:
            return (f"BIC gain {self.information_criterion_delta:.3g}, but no explanation: "
                    f"{self.implausible}")
        ic, margin = self.information_criterion_delta, self.policy.bic_margin
        ratio = self.heldout_ratio
        parts = [
            f"BIC gain {ic:.3g} ({'>' if ic > margin else '<='} {margin:g})",
            f"held-out error x{ratio:.3g} (above noise x{self.heldout_excess_ratio:.3g}): "
            f"{'better' if self.heldout_helps else 'no clear gain'}",
        ]
        invariant = self.invariant_ratio
        if invariant is not None and self.forecast_z is None:
            parts[1] = (
                f"invariant-statistics distance x{invariant:.3g} "
                f"({'<' if invariant < self.policy.invariant_ratio else '>='} "
                f"{self.policy.invariant_ratio:g})"
            )
        elif invariant is not None:
            veto = max(1.0, 1.0 / ratio)
            parts.append(f"its long run's invariant-statistics distance x{invariant:.3g} "
                         f"({'vetoes' if invariant >= veto else 'under'} x{veto:.3g})")
        return ", ".join(parts)


def choose(verdicts: list[Verdict]) -> Verdict | None:
    """The best-scoring candidate that both judges accept, or None (``none``).

    When the second judge is one realization's invariant statistics alone (a chaotic
    record without forecasts), it is noisy enough to veto the best-fitting candidate, not
    to promote a worse fit over it, so there a veto of the best fit means ``none``.
    """
    for verdict in sorted(verdicts, key=lambda v: -v.information_criterion_delta):
        if verdict.earns_keep:
            return verdict
        if (verdict.invariant_ratio is not None and verdict.forecast_z is None
                and verdict.information_criterion_delta > verdict.policy.bic_margin):
            return None
    return None


def paired_gain_z(base: np.ndarray, candidate: np.ndarray,
                  blocks: Iterable[tuple[int, int]]) -> float | None:
    """The drop of the mean-square error from ``base`` to ``candidate`` (two models' errors
    on the same held-out samples, NaN where none), in standard errors of its mean over the
    ``blocks`` (index ranges) taken one by one: a paired test, since the same noise enters
    both, so a small real gain shows where an unpaired one would drown in the noise's own
    scatter.  None with fewer than 3 blocks that hold samples."""
    gains = []
    for a, b in blocks:
        rb, rc = base[a:b], candidate[a:b]
        both = np.isfinite(rb) & np.isfinite(rc)
        if np.count_nonzero(both) >= 2:
            gains.append(float(np.mean(rb[both] ** 2) - np.mean(rc[both] ** 2)))
    if len(gains) < 3:
        return None
    g = np.asarray(gains)
    spread = float(np.std(g, ddof=1)) / math.sqrt(g.size)
    if not spread > 0:
        return math.inf if g.mean() > 0 else -math.inf
    return float(g.mean() / spread)


def heldout_rms(prediction: np.ndarray, data: np.ndarray, valid: np.ndarray, start: int) -> float:
    """RMS prediction error over the valid samples from index ``start`` on."""
    use = valid.copy()
    use[:start] = False
    if not np.any(use):
        return math.nan
    r = prediction[use] - data[use]
    return float(math.sqrt(np.mean(r * r)))
