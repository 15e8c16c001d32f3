"""The grabber threads of :class:`~tactile_force.edge.runtime.loop.ForceRuntime`: one reader thread
per sensor, each holding at most one read ahead (a one-slot hand-over), so no sensor ever
waits for another's camera. :func:`read_once` is one timed ``read()`` of a source (the
loop's own thread uses it when there are no grabbers)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, TypeVar

from ..errors import SourceError
from ..frames import FrameSource, TimedFrame


class GrabbedSensor(Protocol):
    """What a grabber needs from a sensor (:class:`~tactile_force.edge.runtime.loop.Sensor`)."""

    @property
    def name(self) -> str: ...

    @property
    def source(self) -> FrameSource: ...


S = TypeVar("S", bound=GrabbedSensor)

@dataclass(slots=True)
class Read:
    """One read() of a source: the frame (None at the end of the stream), or the SourceError
    it raised; t0 / t1: clock before / after the call (ns)."""

    tf: TimedFrame | None
    error: SourceError | None
    t0: int
    t1: int


def read_once(source: FrameSource, clock: Callable[[], int]) -> Read:
    """One ``source.read()`` timed with ``clock`` (ns); a SourceError is returned, not raised
    (anything else propagates)."""
    t0 = clock()
    try:
        tf = source.read()
    except SourceError as exc:
        return Read(None, exc, t0, clock())
    return Read(tf, None, t0, clock())


class Grabbers:
    """One reader thread per sensor, each holding at most one read ahead (a one-slot
    hand-over: lossless for file sources; live cameras drop old frames themselves).
    :meth:`take` waits until at least one live sensor's read is there and takes every one
    that is (a slow or blocked sensor holds up no other); a source raising anything but
    SourceError re-raises in the loop's thread.

    One lock guards the slots; the loop waits on one condition (a read is there), each
    grabber on its own (its slot was taken), so a hand-over wakes one thread, however many
    sensors there are."""

    def __init__(self, sensors: Sequence[GrabbedSensor], clock: Callable[[], int]) -> None:
        lock = threading.Lock()
        self._cond = threading.Condition(lock)  # the loop's: a read or a failure is there
        self._free = {s.name: threading.Condition(lock) for s in sensors}  # each grabber's: its slot is empty
        self._slots: dict[str, Read | None] = {s.name: None for s in sensors}
        self._failure: BaseException | None = None
        self._stop = False
        self._retire = False
        self._threads = [threading.Thread(target=self._loop, args=(s, clock), name=f"read-{s.name}", daemon=True)
                         for s in sensors]
        for t in self._threads:
            t.start()

    def _loop(self, s: GrabbedSensor, clock: Callable[[], int]) -> None:
        while True:
            try:
                r = read_once(s.source, clock)
            except BaseException as exc:  # noqa: BLE001 - handed to the loop's thread
                with self._cond:
                    self._failure = exc
                    self._cond.notify_all()
                return
            free = self._free[s.name]
            with self._cond:
                while self._slots[s.name] is not None and not self._stop:
                    free.wait()
                if self._stop:
                    return
                self._slots[s.name] = r
                self._cond.notify_all()  # the loop's thread only waits on it
                retire = self._retire
            if r.tf is None or retire:  # end of the stream, a source error, or retired: done
                return

    def wait_all(self, live: Sequence[S], timeout_s: float) -> bool:
        """Wait up to ``timeout_s`` until every live sensor's read is there; True if it is."""
        with self._cond:
            return self._cond.wait_for(lambda: self._failure is not None
                                       or all(self._slots[s.name] is not None for s in live), timeout_s)

    def retire(self) -> None:
        """Let each thread end once it has handed over the read under way (none is lost): the
        loop's thread reads the sources itself again once :meth:`retired`."""
        with self._cond:
            self._retire = True

    @property
    def retiring(self) -> bool:
        return self._retire

    def retired(self) -> bool:
        """True once :meth:`retire` was called, every thread has ended and every read was
        taken (until then :meth:`take` still gets each pending read)."""
        with self._cond:
            return (self._retire and all(r is None for r in self._slots.values())
                    and not any(t.is_alive() for t in self._threads))

    def ready(self, live: Sequence[S]) -> bool:
        """Whether a read of any of ``live`` (or a failure) waits to be taken: a glance
        without the lock (a warm-up asks between its parts whether to give way)."""
        slots = self._slots
        return self._failure is not None or any(slots[s.name] is not None for s in live)

    def take(self, live: Sequence[S], timeout_s: float | None = None) -> list[tuple[S, Read]]:
        """Every live sensor's waiting read, in sensor order: at least one, or none when
        ``timeout_s`` seconds passed first (None: wait as long as it takes)."""
        with self._cond:
            self._cond.wait_for(lambda: self._failure is not None
                                or any(self._slots[s.name] is not None for s in live), timeout_s)
            if self._failure is not None:
                raise self._failure
            got = []
            for s in live:
                r = self._slots[s.name]
                if r is not None:
                    got.append((s, r))
                    self._slots[s.name] = None
                    self._free[s.name].notify()  # that sensor's grabber may read its next frame
            return got

    def stop(self, timeout_s: float = 1.0) -> None:
        """Let every thread end (a thread blocked in ``read()`` ends once it returns) and
        join them for up to ``timeout_s`` seconds in all (not per thread: closing a runtime
        with many blocked sensors takes no longer than with one)."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
            for free in self._free.values():
                free.notify_all()
        end = time.monotonic() + timeout_s
        for t in self._threads:
            t.join(max(0.0, end - time.monotonic()))
