"""Many short runs of one model in one compiled call: the segments of a multiple-shooting fit.

Each segment starts from its own (time, theta, theta') and is sampled at its own times;
the last requested time of a segment is its end, whose state the caller compares with
the next segment's start.  The loop over segments runs in the compiled code
(``integrator.integrate_segments``: no Python per segment), and releases the GIL so that
finite-difference columns of a Jacobian run in threads.
"""

from __future__ import annotations

import numpy as np

from analysis.packed import P
from analysis.simulate import integrator as ig
from analysis.simulate.simulation import check_step_settings


def checked_segments(
    packed: np.ndarray, t0: np.ndarray, state0: np.ndarray, out_t: np.ndarray,
    bounds: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The arguments of a segments run as contiguous arrays; ValueError, saying which, when
    their shapes disagree, the bounds do not cut ``out_t`` into non-empty segments or a
    start state is not finite."""
    p = np.ascontiguousarray(packed, dtype=float)
    if p.shape != (P.SIZE,):
        raise ValueError(f"packed vector has shape {p.shape}; expected ({int(P.SIZE)},)")
    t0 = np.ascontiguousarray(t0, dtype=float)
    state0 = np.ascontiguousarray(state0, dtype=float)
    bounds = np.ascontiguousarray(bounds, dtype=np.int64)
    out_t = np.ascontiguousarray(out_t, dtype=float)
    if state0.shape != (t0.size, 2) or bounds.shape != (t0.size + 1,):
        raise ValueError(
            f"{t0.size} segments need state0 of shape ({t0.size}, 2) and {t0.size + 1} bounds; "
            f"got {state0.shape} and {bounds.shape}"
        )
    if bounds[0] != 0 or bounds[-1] != out_t.size or np.any(np.diff(bounds) < 1):
        raise ValueError("bounds must start at 0, end at len(out_t) and give each segment a time")
    if not np.all(np.isfinite(state0)):
        raise ValueError("segment start states must be finite")
    return p, t0, state0, out_t, bounds


def integrate_segments(
    packed: np.ndarray,
    t0: np.ndarray,
    state0: np.ndarray,
    out_t: np.ndarray,
    bounds: np.ndarray,
    *,
    rtol: float = 1e-8,
    atol: float = 1e-10,
    max_steps: int = ig.DEFAULT_MAX_STEPS,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run segment k from (t0[k], state0[k]) and sample it at out_t[bounds[k]:bounds[k+1]].

    ``out_t`` holds every segment's times, increasing within a segment and not before its
    start; the last time of a segment is where it ends.  Returns theta and theta' at
    ``out_t`` (NaN where a run stopped early) and each segment's status code
    (``integrator.STATUS_NAMES``).  ``max_steps`` caps each segment's steps: a fit's trial
    parameters can make the contact absurdly stiff, and such a trial should fail fast.
    """
    p, t0, state0, out_t, bounds = checked_segments(packed, t0, state0, out_t, bounds)
    check_step_settings(rtol, atol)
    out_th = np.empty(out_t.size)
    out_om = np.empty(out_t.size)
    status = np.zeros(t0.size)
    ig.integrate_segments(p, t0, state0[:, 0].copy(), state0[:, 1].copy(), out_t, bounds, rtol,
                        atol, int(max_steps), out_th, out_om, status)
    return out_th, out_om, status.astype(np.int64)
