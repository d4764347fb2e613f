"""BLAS on one thread for the whole process, once an analysis starts.

A fitted value, and so a marginal choice between causes, must not depend on how many
threads the linear algebra had: multithreaded BLAS sums in an order that changes with the
thread count, and a machine's core count would show in the report
(``tests/discrepancy/test_hidden_cause.py``, the impact decay with drag, is the
regression test).  The fits share the cores out over threads of their own; BLAS threads
beside them would only spin.
"""

from __future__ import annotations

from threadpoolctl import threadpool_limits


def blas_on_one_thread() -> None:
    """Hold BLAS to one thread for the process (idempotent)."""
    threadpool_limits(1, user_api="blas")
