"""The workers of a :class:`~tactile_force.edge.runtime.loop.ForceRuntime` with several sensors:
when two or more sensors' frames are ready in one step, their per-sensor work (contact gate,
sensor watch, depth stage) runs on up to ``n`` threads at once, the loop's own thread
included; the step's one batched predict and every reading's bookkeeping stay in the loop's
thread. OpenCV, numpy and onnxruntime release the GIL in their calls, so on a host with two
cores a queue of ready frames drains about twice as fast.

Each sensor's parts belong to it alone (edge/runtime/ownership.py), so two threads never
touch one part. A step with one frame ready runs it in the loop's thread: no hand-over, no
extra cost. :func:`worker_count` is the ``RuntimeOptions.workers`` rule.
"""

from __future__ import annotations

import os
import queue
import threading
import time
from collections.abc import Callable, Sequence
from typing import Generic, TypeVar

T = TypeVar("T")


def host_cores() -> int:
    """CPU cores this process may run on (its affinity where the OS tells it, else the count)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        return os.cpu_count() or 1


def worker_count(asked: int | None, sensors: int, real_clock: bool, cores: int | None = None) -> int:
    """Threads that run a step's per-sensor work, the loop's own included.

    Parameters
    ----------
    asked
        ``RuntimeOptions.workers`` (None: auto).
    sensors
        Sensors of the runtime.
    real_clock
        The runtime runs on ``time.monotonic_ns`` (an injected clock drives a test step by
        step: auto keeps one thread, so the clock is read in one order).
    cores
        Cores of the host (default :func:`host_cores`).

    Returns
    -------
    int
        ``asked`` when given, at most one per sensor; auto: 2 with several sensors, two or more
        cores and the real clock, else 1.
    """
    if asked is not None:
        return max(1, min(int(asked), sensors))
    cores = host_cores() if cores is None else cores
    return 2 if sensors > 1 and cores >= 2 and real_clock else 1


class _Job(Generic[T]):
    """One step's items: each claimed by one thread (the next unclaimed), worked, counted."""

    __slots__ = ("fn", "items", "next", "left", "lock", "done", "error")

    def __init__(self, fn: Callable[[T], None], items: Sequence[T]) -> None:
        self.fn, self.items = fn, items
        self.next = 0
        self.left = len(items)
        self.lock = threading.Lock()
        self.done = threading.Event()
        self.error: BaseException | None = None

    def work(self) -> None:
        """Claim and work items until none is left unclaimed (any thread, any number of them)."""
        items, lock = self.items, self.lock
        while True:
            with lock:
                i = self.next
                if i >= len(items):
                    return
                self.next = i + 1
            try:
                self.fn(items[i])
            except BaseException as exc:  # noqa: BLE001 - re-raised in the loop's thread
                with lock:
                    self.error = self.error or exc
            with lock:
                self.left -= 1
                if not self.left:
                    self.done.set()


class Workers:
    """``n`` threads over a step's items: the caller's and ``n - 1`` helper threads (daemons,
    started at the first step with two items or more).

    Parameters
    ----------
    n
        Threads in all (>= 1; 1: every item in the caller's thread).
    name
        Prefix of the helper threads' names (``work-<name>-1``, ...).
    """

    def __init__(self, n: int, name: str = "runtime") -> None:
        self.n = max(1, n)
        self._name = name
        self._queue: queue.SimpleQueue[_Job | None] = queue.SimpleQueue()
        self._threads: list[threading.Thread] = []
        self._stopped = False

    def run(self, fn: Callable[[T], None], items: Sequence[T]) -> None:
        """``fn(item)`` for every item, spread over the threads; returns when all are done.
        The first exception an item raised is raised here (after every item was worked)."""
        if self.n == 1 or len(items) < 2 or self._stopped:
            for item in items:
                fn(item)
            return
        if not self._threads:
            self._start()
        job = _Job(fn, items)
        for _ in range(min(self.n - 1, len(items) - 1)):
            self._queue.put(job)
        job.work()  # the caller's thread works too: a helper that wakes late finds nothing left
        job.done.wait()
        if job.error is not None:
            raise job.error

    def _start(self) -> None:
        for k in range(self.n - 1):
            t = threading.Thread(target=self._loop, name=f"work-{self._name}-{k + 1}", daemon=True)
            t.start()
            self._threads.append(t)

    def _loop(self) -> None:
        while (job := self._queue.get()) is not None:
            job.work()

    def stop(self, timeout_s: float = 1.0) -> None:
        """End the helper threads (each finishes the item it works on first) and join them for
        up to ``timeout_s`` seconds in all (not per thread). Idempotent."""
        self._stopped = True
        for _ in self._threads:
            self._queue.put(None)
        end = time.monotonic() + timeout_s
        for t in self._threads:
            t.join(max(0.0, end - time.monotonic()))
        self._threads = []
