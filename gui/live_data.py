"""What the views draw: the newest seconds of every channel, tach edges and the drive, in memory.

Filled on the GUI thread from the engine subscription (a bounded queue drained on a
timer); views read slices of it when they redraw.  Fixed-size rings: the memory
does not grow with the length of a run, and an old sample is simply overwritten.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable

import numpy as np

from drivers.interfaces import PulseBlock, SampleBlock
from gui.units import DISPLAY
from rig.events import DriveSetting, Gap, StepBegun, StepMark

DEFAULT_KEEP_S = 30.0
MAX_TACH_EDGES = 100_000
TACH_PERIODS = 16  # the drive frequency is measured over at most this many newest periods
# Pulse spacings alike: within two samples (each mark is a whole sample late by up to one)
# and 1 % of the newest (a sweep's step moves it by more)
SPACING_SAMPLES = 2.0
SPACING_RELATIVE = 0.01


class ChannelRing:
    """The newest ``capacity`` samples of one channel with their device sample indices."""

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"capacity = {capacity}: need room for at least one sample")
        self.capacity = int(capacity)
        self._values = np.zeros(self.capacity, dtype=np.float64)
        self._indices = np.zeros(self.capacity, dtype=np.int64)
        self._write = 0
        self.count = 0  # samples held (at most capacity)
        self.end_index: int | None = None  # one past the newest sample index

    def append(self, first_index: int, values: np.ndarray) -> None:
        """Add consecutive samples starting at device index ``first_index``."""
        values = np.asarray(values, dtype=np.float64)
        n = values.size
        if n == 0:
            return
        indices = first_index + np.arange(n, dtype=np.int64)
        if n >= self.capacity:
            values, indices = values[-self.capacity :], indices[-self.capacity :]
            n = self.capacity
        stop = self._write + n
        if stop <= self.capacity:
            self._values[self._write : stop] = values
            self._indices[self._write : stop] = indices
        else:
            split = self.capacity - self._write
            self._values[self._write :] = values[:split]
            self._indices[self._write :] = indices[:split]
            self._values[: n - split] = values[split:]
            self._indices[: n - split] = indices[split:]
        self._write = stop % self.capacity
        self.count = min(self.capacity, self.count + n)
        self.end_index = int(indices[-1]) + 1

    def latest(self, n: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The newest ``n`` samples (all held when None), oldest first: (indices, values)."""
        n = self.count if n is None else max(0, min(int(n), self.count))
        start = self._write - n
        if start >= 0:
            return self._indices[start : self._write].copy(), self._values[
                start : self._write
            ].copy()
        return (
            np.concatenate([self._indices[start:], self._indices[: self._write]]),
            np.concatenate([self._values[start:], self._values[: self._write]]),
        )

    def since(self, first_index: int) -> tuple[np.ndarray, np.ndarray]:
        """Samples with index >= ``first_index`` that are still held."""
        if self.end_index is None:
            return np.zeros(0, np.int64), np.zeros(0)
        return self.latest(self.end_index - first_index)

    def clear(self) -> None:
        """Forget everything (a new source or a seek)."""
        self._write = 0
        self.count = 0
        self.end_index = None


class LiveData:
    """The newest data of the angle, the table and the tach, as the views need it."""

    def __init__(
        self,
        sample_rate_hz: float,
        keep_s: float = DEFAULT_KEEP_S,
        *,
        origin_index: int | None = None,
        equivalent_length_m: float | None = None,
        recorded_steps: Iterable[StepMark] = (),
    ) -> None:
        """``origin_index`` is the source's first sample (time zero of the views; default:
        the first sample that arrives), ``equivalent_length_m`` the rig's L (None: unknown,
        no beta), ``recorded_steps`` a recording's sweep steps, known before they play."""
        self.sample_rate_hz = float(sample_rate_hz)
        self.keep_s = keep_s
        self.origin_index = origin_index
        self.equivalent_length_m = equivalent_length_m
        self.recorded_steps = tuple(recorded_steps)
        capacity = max(1024, int(keep_s * self.sample_rate_hz))
        self.angle = ChannelRing(capacity)
        self.table = ChannelRing(capacity)
        self.tach_edges: deque[int] = deque(maxlen=MAX_TACH_EDGES)
        self.tach_edges_seen = 0  # all edges ever added (views track their own progress)
        self.drive: DriveSetting | None = None
        self.steps: list[StepMark] = list(self.recorded_steps)
        self.steps_begun: list[StepBegun] = []  # live sweeps: steps under way have no mark yet
        self.gaps = 0
        self.samples_in = 0
        self.generation = 0  # bumped by clear(): views drop what they accumulated

    def ingest(self, events: Iterable[object]) -> None:
        """Take the engine's deliveries (sample and pulse blocks, gaps, drive, steps)."""
        for event in events:
            if isinstance(event, SampleBlock):
                ring = self.angle if event.channel == "angle" else None
                if ring is None and event.channel == "table":
                    ring = self.table
                if ring is not None:
                    if self.origin_index is None:
                        self.origin_index = event.first_index
                    ring.append(event.first_index, event.values)
                    self.samples_in += len(event)
            elif isinstance(event, PulseBlock):
                for edge in event.edge_indices:
                    self.tach_edges.append(int(edge))
                    self.tach_edges_seen += 1
            elif isinstance(event, DriveSetting):
                self.drive = event
            elif isinstance(event, StepMark) and event not in self.recorded_steps:
                self.steps.append(event)
            elif isinstance(event, StepBegun):
                self.steps_begun.append(event)
            elif isinstance(event, Gap):
                self.gaps += 1

    def seconds(self, indices: np.ndarray | int) -> np.ndarray:
        """Sample indices as seconds from the start of the source (not device time)."""
        return (np.asarray(indices) - (self.origin_index or 0)) / self.sample_rate_hz

    def current_step(self) -> StepMark | StepBegun | None:
        """The newest sweep step that began before the newest sample (None: no sweep): its
        mark once it ended, else the news that it began."""
        end = self.angle.end_index
        if end is None:
            return None
        begun = [mark for mark in [*self.steps_begun, *self.steps] if mark.settle_start_index < end]
        return max(
            begun,
            key=lambda mark: (mark.settle_start_index, isinstance(mark, StepMark)),
            default=None,
        )

    def step_starts(self) -> dict[int, int]:
        """Where each sweep step began (sample index -> step number), ended or under way."""
        return {m.settle_start_index: m.step for m in [*self.steps_begun, *self.steps]}

    def drive_frequency_hz(self) -> float | None:
        """The drive frequency: from the tach when it ticks, else the last drive setting.

        From the newest run of pulses spaced alike (up to TACH_PERIODS periods; a missed
        or doubled pulse, or a new drive setting, ends the run): over n periods the
        whole-sample marks err by a sample in n periods, not in one or two."""
        edges = np.fromiter(
            (self.tach_edges[i] for i in range(max(0, len(self.tach_edges) - TACH_PERIODS - 1),
                                               len(self.tach_edges))), dtype=np.int64)
        if edges.size >= 3:
            spacing = np.diff(edges).astype(float)
            newest = spacing[-1]
            alike = np.abs(spacing - newest) <= SPACING_SAMPLES + SPACING_RELATIVE * newest
            run = spacing.size if alike.all() else int(np.argmin(alike[::-1]))
            period = (edges[-1] - edges[-1 - run]) / run
            end = self.angle.end_index or 0
            if run >= 2 and period > 0 and end - edges[-1] < 3 * period:
                return self.sample_rate_hz / period
        if self.drive is not None and self.drive.enabled and self.drive.frequency_hz > 0:
            return self.drive.frequency_hz
        return None

    def clear(self) -> None:
        """Forget all data (a new source, or a replay seek)."""
        self.angle.clear()
        self.table.clear()
        self.tach_edges.clear()
        self.tach_edges_seen = 0
        self.steps = list(self.recorded_steps)
        self.steps_begun.clear()
        self.gaps = 0
        self.generation += 1


def drive_description(data: LiveData) -> str:
    """The drive in force and the sweep step, as the operator reads them (Hz, mm, beta)."""
    drive = data.drive
    if drive is None:
        text = "drive: none recorded"
    elif not drive.enabled:
        text = "drive: off"
    else:
        amplitude = DISPLAY["displacement"]
        text = (
            f"drive: {drive.frequency_hz:.3f} Hz, "
            f"{amplitude.show(drive.amplitude_m):.3f} {amplitude.unit}"
        )
        if data.equivalent_length_m:
            text += f", β = A/L = {drive.amplitude_m / data.equivalent_length_m:.4f}"
    step = data.current_step()
    if step is not None:
        ended = isinstance(step, StepMark) and (data.angle.end_index or 0) > step.dwell_end_index
        where = "after" if ended else "in"
        steps_in_plan = step.of_steps if isinstance(step, StepBegun) else len(data.recorded_steps)
        total = f" of {steps_in_plan}" if steps_in_plan else ""
        text += f"   |   {where} sweep step {step.step + 1}{total}"
    return text
