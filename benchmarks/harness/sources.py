"""Frame sources over frames already in memory: what the runtime reads when decoding or
rendering is not part of the measurement.

- :class:`MemorySource`: frames cycled ``n`` times in all, each arriving when read;
- :class:`ListSource`: each frame read once, with its true force;
- :class:`PacedMemorySource`: a camera stand-in, frame i due at t0 + offset + i / fps.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np
from tactile_force.edge.frames import FrameSource, TimedFrame

Clock = Callable[[], int]


class MemorySource(FrameSource):
    """A FrameSource over frames already in memory (cycled ``n`` times in all): what the
    runtime reads when decoding or rendering is not part of the measurement. Each frame
    arrives when read() is called (``arrival_ns``)."""

    name = "memory"

    def __init__(self, frames: np.ndarray, n: int, clock: Clock = time.monotonic_ns) -> None:
        super().__init__()
        self.frames, self.n, self.clock = frames, n, clock

    def read(self) -> TimedFrame | None:
        i = self.stats.frames
        if i >= self.n:
            return None
        self.stats.frames += 1
        now = self.clock()
        return TimedFrame(self.frames[i % len(self.frames)], now, i, arrival_ns=now)


class ListSource(FrameSource):
    """A finite FrameSource over frames in memory, each read once, with its true force (N;
    None = unknown or cannot be judged): what the error, trust and stability pages feed the
    runtime. Each frame arrives when read() is called (``arrival_ns``)."""

    name = "memory"

    def __init__(self, frames: Sequence[np.ndarray] | np.ndarray, truth: Sequence[float | None] | None = None,
                 clock: Clock = time.monotonic_ns) -> None:
        super().__init__()
        self.frames, self.clock = frames, clock
        self.truth: list[float | None] = list(truth) if truth is not None else [None] * len(frames)

    def read(self) -> TimedFrame | None:
        i = self.stats.frames
        if i >= len(self.frames):
            return None
        self.stats.frames += 1
        now = self.clock()
        return TimedFrame(self.frames[i], now, i, self.truth[i], arrival_ns=now)


class PacedMemorySource(FrameSource):
    """A camera stand-in over frames in memory: frame i is due at t0 + offset + i/fps; read()
    waits for it and stamps arrival when it has it (a reader that was late: when it fell
    due), skipping frames a slow reader missed (listed as superseded) like a camera's
    newest-frame grabber. ``missed``: the skipped frames from index ``count_from`` on (the
    measured ones, after a warm-up); ``stats.dropped`` counts every skipped frame."""

    def __init__(self, frames: np.ndarray, fps: float, n: int, offset_s: float = 0.0, name: str = "cam",
                 count_from: int = 0) -> None:
        super().__init__()
        self.frames, self.period, self.n, self.name = frames, int(1e9 / fps), n, name
        self.count_from, self.missed = count_from, 0
        self.offset = int(offset_s * 1e9)
        self.t0: int | None = None
        self.next = 0

    def read(self) -> TimedFrame | None:
        now = time.monotonic_ns()
        if self.t0 is None:
            self.t0 = now + self.offset
        if self.next >= self.n:
            return None
        i = self.next
        due = self.t0 + i * self.period
        superseded: list[tuple[int, int]] = []
        arrival = due  # a frame the reader is late for waited in the buffer since it fell due
        if due > now:
            time.sleep((due - now) / 1e9)
            arrival = time.monotonic_ns()  # like a camera grab: stamped when the frame is in hand
        else:
            newest = int(min(self.n - 1, (now - self.t0) // self.period))
            if newest > i:
                superseded = [(k, self.t0 + k * self.period) for k in range(i, newest)]
                self.missed += max(0, newest - max(i, self.count_from))
                i, due = newest, self.t0 + newest * self.period
                self.stats.dropped += len(superseded)
            arrival = due
        self.next = i + 1
        self.stats.frames += 1
        return TimedFrame(self.frames[i % len(self.frames)], due, i, meta={"superseded": superseded},
                          arrival_ns=arrival)

