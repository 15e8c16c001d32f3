"""A guard against threads a test leaves running: every Python thread a test (or its
function-scoped fixtures) started must have ended by the end of its teardown, after a short
join grace. A thread left alive fails the test at teardown, naming the thread and the target
that started it; a later test would otherwise run beside it (a signal may reach its handler
late, a grabber may still read a closed source).

Not counted: tqdm's monitor thread (tqdm starts one per process and keeps it for later bars),
threads a foreign library's native code calls Python from (``threading._DummyThread``: not
startable or joinable from Python), and threads named in :data:`ALLOWED` (each with its reason).

``TF_THREAD_GUARD=report`` only writes what leaked (one line per test) to stderr and to the file
``TF_THREAD_GUARD_LOG`` names, instead of failing: the diagnostic mode.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Iterator

import pytest

#: Join grace, in seconds, for all the threads a test left together (not per thread).
GRACE_S = 2.0

#: Thread-name prefixes a test may leave alive, each with why.
ALLOWED: dict[str, str] = {}


def _foreign(t: threading.Thread) -> bool:
    """A thread the guard does not judge: tqdm's monitor, a native thread's dummy, an allowed name."""
    if isinstance(t, threading._DummyThread):  # type: ignore[attr-defined]
        return True
    mod = type(t).__module__ or ""
    if mod.startswith("tqdm"):  # tqdm._monitor.TMonitor: one per process, kept for later bars
        return True
    return any(t.name.startswith(p) for p in ALLOWED)


def _describe(t: threading.Thread) -> str:
    target = getattr(t, "_target", None)
    where = getattr(target, "__qualname__", None) or type(t).__qualname__
    owner = getattr(getattr(target, "__self__", None), "__class__", None)
    if owner is not None:
        where = f"{owner.__module__}.{where}"
    return f"{t.name!r} ({'daemon' if t.daemon else 'non-daemon'}, {where})"


def left_alive(before: set[threading.Thread], grace_s: float = GRACE_S) -> list[threading.Thread]:
    """Threads alive now that were not in ``before`` and are still alive after joining them for up
    to ``grace_s`` seconds in all (no wait when there are none)."""
    new = [t for t in threading.enumerate() if t not in before and not _foreign(t)]
    if not new:
        return []
    end = time.monotonic() + grace_s
    for t in new:
        t.join(max(0.0, end - time.monotonic()))
    return [t for t in new if t.is_alive()]


@pytest.fixture(autouse=True)
def thread_guard(request: pytest.FixtureRequest) -> Iterator[None]:
    """Fail the test at teardown when it left a thread running (see the module's docstring)."""
    before = set(threading.enumerate())
    yield
    alive = left_alive(before)
    if not alive:
        return
    names = ", ".join(_describe(t) for t in alive)
    if os.environ.get("TF_THREAD_GUARD") == "report":
        line = f"LEAK {request.node.nodeid}: {names}"
        print(line, file=sys.stderr)
        log = os.environ.get("TF_THREAD_GUARD_LOG")
        if log:
            with open(log, "a", encoding="utf-8") as f:
                f.write(line + "\n")
        return
    pytest.fail(f"the test left {len(alive)} thread(s) running {GRACE_S:g} s after its teardown: {names}; close "
                "what started them (a runtime, a source, an output) in the test or its fixture", pytrace=False)
