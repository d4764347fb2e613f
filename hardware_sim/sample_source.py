"""What feeds a simulated DAQ board: any object that produces the next n raw samples.

The virtual rig (physics) and the deterministic counter source below both fit
:class:`SampleSource`; the board emulator and the tests' in-process backend
take either.  Channel names are the board's signal names: ``'angle'`` and
``'table'`` (ADC counts, int) and ``'tach'`` (bool per sample).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class SampleSource(Protocol):
    """Produces raw samples at its configured rate; consecutive calls continue in time."""

    sample_rate_hz: float

    def configure(self, sample_rate_hz: float) -> None:
        """Set the rate of the samples that later ``generate`` calls return."""
        ...

    def generate(self, n: int) -> dict[str, np.ndarray]:
        """The next ``n`` samples: ``{'angle': counts, 'table': counts, 'tach': bool}``."""
        ...


class CounterSource:
    """Deterministic source whose every sample tells its own running index.

    ``angle`` is the index modulo 2**16 (as int16), ``table`` is ``3*i + 11`` modulo
    2**16, and ``tach`` is high for ``tach_width`` samples every ``tach_period``
    samples, starting at index ``tach_phase``.  A receiver can therefore check,
    sample by sample, that nothing was invented, reordered or silently dropped.
    """

    def __init__(
        self,
        sample_rate_hz: float = 10_000.0,
        *,
        tach_period: int = 1000,
        tach_width: int = 10,
        tach_phase: int = 0,
    ) -> None:
        if tach_period < 2 or not 1 <= tach_width < tach_period:
            raise ValueError(
                f"tach_width={tach_width} must be in 1..tach_period-1 (tach_period={tach_period})"
            )
        self.sample_rate_hz = float(sample_rate_hz)
        self.tach_period = tach_period
        self.tach_width = tach_width
        self.tach_phase = tach_phase
        self.next_index = 0

    def configure(self, sample_rate_hz: float) -> None:
        """Set the rate (the counter itself does not depend on it)."""
        self.sample_rate_hz = float(sample_rate_hz)

    def restart(self) -> None:
        """Begin again at index 0 (the board does this at each START)."""
        self.next_index = 0

    def generate(self, n: int) -> dict[str, np.ndarray]:
        """The next ``n`` samples, each telling its own index (see the class docstring)."""
        index = np.arange(self.next_index, self.next_index + n, dtype=np.int64)
        self.next_index += n
        return {
            "angle": expected_angle_counts(index),
            "table": expected_table_counts(index),
            "tach": self.expected_tach(index),
        }

    def expected_tach(self, index: np.ndarray) -> np.ndarray:
        """The tach level this source gives at the running indices ``index``."""
        return (np.asarray(index) - self.tach_phase) % self.tach_period < self.tach_width

    def expected_rising_edges(self, start: int, stop: int) -> np.ndarray:
        """Indices in ``[start, stop)`` where tach goes from low (at i-1) to high (at i)."""
        first = start + (self.tach_phase - start) % self.tach_period
        edges = np.arange(first, stop, self.tach_period, dtype=np.int64)
        return edges[edges >= 1]  # sample 0 has no predecessor, so it cannot be an edge


def expected_angle_counts(index: np.ndarray) -> np.ndarray:
    """Counter source's angle channel at the given running indices."""
    return (np.asarray(index, dtype=np.int64) & 0xFFFF).astype(np.uint16).view(np.int16)


def expected_table_counts(index: np.ndarray) -> np.ndarray:
    """Counter source's table channel at the given running indices."""
    return ((3 * np.asarray(index, dtype=np.int64) + 11) & 0xFFFF).astype(np.uint16).view(np.int16)
