"""BLAS on one thread for the whole process, once an analysis starts.

A fitted value must not depend on how many threads the linear algebra had: with two BLAS
threads a shooting fit's value differed from one's in the eighth digit, and a decay's
marginal choice (quadratic drag in an impact decay, seed 3902 of the reference decays)
came out one way on one thread and the other way on two, so a machine's core count, or
whether a forced record had been analysed before in the same process, would show.  The
fits share the cores out over threads of their own; BLAS threads beside them would only
spin (a quarter of a screening fit's time on 2 cores).
"""

from __future__ import annotations

from threadpoolctl import threadpool_limits


def blas_on_one_thread() -> None:
    """Hold BLAS to one thread for the process (idempotent)."""
    threadpool_limits(1, user_api="blas")
