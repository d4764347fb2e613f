"""Keep None, True and False alive under PySide6 6.12 on CPython 3.11.

That PySide6 drops one reference to ``None`` on every call of a Qt method that
returns nothing (``setText``, ``update``, ``processEvents`` ...); pyqtgraph makes
thousands per second, so after ten to thirty seconds of live plotting CPython frees
``None`` and aborts ("none_dealloc").  From Python 3.12 these objects are immortal
and the bug is harmless; before it, we give them the same effective immortality by
raising their reference counts once by 2**40 (years of calls at any frame rate).
"""

from __future__ import annotations

import ctypes
import sys

RESERVE = 1 << 40


def protect_singletons() -> bool:
    """Raise the reference counts of None, True and False once; True when it was needed."""
    if sys.implementation.name != "cpython" or sys.version_info >= (3, 12):
        return False
    for obj in (None, True, False):
        count = ctypes.c_ssize_t.from_address(id(obj))  # ob_refcnt is a PyObject's first field
        if count.value < RESERVE // 2:
            count.value += RESERVE
    return True
