"""Join the sample blocks of several channels on their shared device sample index.

Channels of one DAQ board share a running index but arrive as separate blocks, at
different moments and with their own gaps.  A subscriber that needs the angle and the
table side by side feeds every block to a ``ChannelAligner`` and takes back the index
ranges that all channels hold; a range missing from any channel is never filled in.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from drivers.interfaces import SampleBlock


@dataclass(frozen=True)
class AlignedBlock:
    """Samples ``[first_index, first_index + n)`` of every channel."""

    first_index: int
    values: dict[str, np.ndarray]

    def __len__(self) -> int:
        return int(next(iter(self.values.values())).size)


class ChannelAligner:
    """Buffers blocks per channel and releases the index ranges every channel has."""

    def __init__(self, channels: Sequence[str]) -> None:
        if not channels:
            raise ValueError("a ChannelAligner needs at least one channel")
        self.channels = tuple(channels)
        self._pending: dict[str, deque[tuple[int, np.ndarray]]] = {c: deque() for c in channels}
        self.unaligned_samples = 0  # samples dropped because another channel lacked them

    def add(self, block: SampleBlock) -> None:
        """Buffer a block (blocks of other channels are ignored)."""
        if block.channel in self._pending and len(block):
            self._pending[block.channel].append((block.first_index, np.asarray(block.values)))

    def pop(self) -> list[AlignedBlock]:
        """The aligned ranges available now, contiguous ranges merged, oldest first."""
        out: list[AlignedBlock] = []
        queues = [self._pending[c] for c in self.channels]
        while all(queues):
            low = max(q[0][0] for q in queues)
            if not all(self._trim_before(q, low) for q in queues):
                continue
            high = min(q[0][0] + q[0][1].size for q in queues)
            values = {c: q[0][1][: high - low] for c, q in zip(self.channels, queues, strict=True)}
            for q in queues:
                first, data = q.popleft()
                if first + data.size > high:
                    q.appendleft((high, data[high - first :]))
            if out and out[-1].first_index + len(out[-1]) == low:
                merged = {c: np.concatenate([out[-1].values[c], values[c]]) for c in values}
                out[-1] = AlignedBlock(out[-1].first_index, merged)
            else:
                out.append(AlignedBlock(low, values))
        return out

    def _trim_before(self, queue: deque[tuple[int, np.ndarray]], index: int) -> bool:
        """Drop the queue head's samples before ``index``; False when the head emptied."""
        first, data = queue[0]
        if first >= index:
            return True
        queue.popleft()
        cut = min(index - first, data.size)
        self.unaligned_samples += cut
        if cut < data.size:
            queue.appendleft((index, data[cut:]))
            return True
        return False
