"""edge/runtime/grabbers.py on its own: the one-slot hand-over, a source raising SourceError, a
failure re-raised in the loop's thread, stop(). The sources are fakes at the camera boundary;
ordering is forced with events, no wall-clock assertions."""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import pytest
from tactile_force.edge import SourceError, TimedFrame
from tactile_force.edge.runtime.grabbers import Grabbers, read_once

WAIT_S = 20.0  # generous: only a hung thread ever gets near it


class FakeCountingSource:
    """Fake camera: frames 0..n-1, then None; counts its reads; ``gate`` (if set) must be set
    before each read after the first returns."""

    def __init__(self, n: int, gate: threading.Event | None = None) -> None:
        self.n, self.reads, self.gate = n, 0, gate
        self.read_started = threading.Event()

    def read(self) -> TimedFrame | None:
        self.read_started.set()
        if self.gate is not None and self.reads > 0:
            self.gate.wait(WAIT_S)
        i = self.reads
        self.reads += 1
        if i >= self.n:
            return None
        return TimedFrame(np.full((2, 2, 3), i, np.uint8), i * 1000, i)

    def close(self) -> None:
        pass


class FakeFailingSource:
    """Fake camera whose read raises ``exc``."""

    def __init__(self, exc: BaseException) -> None:
        self.exc = exc

    def read(self) -> TimedFrame | None:
        raise self.exc

    def close(self) -> None:
        pass


@dataclass
class _S:
    name: str
    source: object


def _clock() -> int:
    _clock.t += 10  # type: ignore[attr-defined]
    return _clock.t  # type: ignore[attr-defined]


_clock.t = 0  # type: ignore[attr-defined]


def test_read_once_times_the_read_and_returns_source_error():
    r = read_once(FakeCountingSource(1), _clock)  # type: ignore[arg-type]
    assert r.error is None and r.tf is not None and r.tf.index == 0 and r.t1 > r.t0
    err = SourceError("camera unplugged")
    r = read_once(FakeFailingSource(err), _clock)  # type: ignore[arg-type]
    assert r.tf is None and r.error is err and r.t1 > r.t0
    with pytest.raises(RuntimeError, match="boom"):  # anything else propagates
        read_once(FakeFailingSource(RuntimeError("boom")), _clock)  # type: ignore[arg-type]


def test_one_slot_hand_over_reads_at_most_one_ahead_and_loses_nothing():
    src = FakeCountingSource(5)
    s = _S("left", src)
    g = Grabbers([s], _clock)  # type: ignore[list-item]
    try:
        assert g.wait_all([s], WAIT_S)  # type: ignore[list-item]
        # the slot is full: the thread has read at most one more frame and waits to hand it over
        seen = []
        while True:
            got = g.take([s])  # type: ignore[list-item]
            assert len(got) == 1 and got[0][0] is s
            assert src.reads <= len(seen) + 2  # the taken read, plus at most one read ahead
            tf = got[0][1].tf
            if tf is None:
                break
            seen.append(tf.index)
        assert seen == [0, 1, 2, 3, 4]  # lossless, in order, then the end of the stream
    finally:
        g.stop()


def test_source_error_is_handed_over_and_ends_that_sensor_only():
    err = SourceError("left camera gone")
    bad, good = _S("left", FakeFailingSource(err)), _S("right", FakeCountingSource(3))
    g = Grabbers([bad, good], _clock)  # type: ignore[list-item]
    try:
        assert g.wait_all([bad, good], WAIT_S)  # type: ignore[list-item]
        got = dict((s.name, r) for s, r in g.take([bad, good]))  # type: ignore[list-item]
        assert got["left"].error is err and got["left"].tf is None
        assert got["right"].error is None and got["right"].tf is not None and got["right"].tf.index == 0
        frames = []
        while True:  # only the right sensor is live now
            (s, r), = g.take([good])  # type: ignore[list-item]
            if r.tf is None:
                break
            frames.append(r.tf.index)
        assert frames == [1, 2]
    finally:
        g.stop()


def test_other_failure_is_re_raised_in_the_loops_thread():
    boom = _S("left", FakeFailingSource(MemoryError("driver bug")))
    g = Grabbers([boom], _clock)  # type: ignore[list-item]
    try:
        assert g.wait_all([boom], WAIT_S)  # type: ignore[list-item]  # a failure ends the wait too
        with pytest.raises(MemoryError, match="driver bug"):
            g.take([boom])  # type: ignore[list-item]
    finally:
        g.stop()


def test_stop_ends_a_thread_waiting_to_hand_over():
    gate = threading.Event()
    src = FakeCountingSource(100, gate)
    s = _S("left", src)
    g = Grabbers([s], _clock)  # type: ignore[list-item]
    assert g.wait_all([s], WAIT_S)  # type: ignore[list-item]
    gate.set()  # the thread reads one more frame and blocks on the full slot
    g.stop(timeout_s=WAIT_S)
    assert all(not t.is_alive() for t in g._threads)
    assert src.reads <= 2  # it stopped instead of reading on


def test_retire_hands_over_the_read_under_way_and_loses_nothing():
    """After retire() the thread ends once it has handed over the read it was making; the
    loop's thread then reads the source itself: every frame exactly once, in order."""
    src = FakeCountingSource(6)
    s = _S("a", src)
    g = Grabbers([s], _clock)  # type: ignore[list-item]
    got = [r.tf.index for _, r in g.take([s], WAIT_S)]  # type: ignore[union-attr]
    g.retire()
    assert g.retiring
    while not g.retired():
        got += [r.tf.index for _, r in g.take([s], WAIT_S)]  # type: ignore[union-attr]
    g.stop()
    while (tf := src.read()) is not None:
        got.append(tf.index)
    assert got == list(range(6))
