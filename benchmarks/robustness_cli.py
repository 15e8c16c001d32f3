"""Robustness categories of the command line's own promises: a signal at the CLI's earliest
moments, numeric arguments at their extremes, the old module paths and names, the bench's
statistics floor and its warm-up misses.

Each entry of :data:`CATEGORIES` is ``(key, name, build)``; ``build(folder, examples)``
returns ``(cases, note)`` with ``cases`` ``(what, probe)`` pairs run by
:func:`benchmarks.robustness_inputs.run_cases`. tests/robustness/test_cli_promises.py runs
the same probes.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from .harness.cases import Outcome, Verdict

Cases = tuple[list[tuple[str, Callable[[], Verdict]]], str]

# =============================================================================== signals at start
#: seconds after the package starts loading at which the early signals are sent
EARLY_DELAYS = (0.0, 0.05, 0.1, 0.2, 0.3)


def cli_argv(*args: str) -> list[str]:
    """``python -m tactile_force.edge.cli ARGS`` (the CLI as the console script starts it)."""
    return [sys.executable, "-m", "tactile_force.edge.cli", *args]


def _package_loading(pid: int) -> bool:
    """Whether process ``pid`` has started loading the package (numpy's core library is
    mapped: the package's first import needs it; Linux /proc)."""
    try:
        return "_multiarray_umath" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


def signal_at_start(args: list[str], sig: int, delay_s: float, timeout_s: float = 120.0
                    ) -> tuple[int | None, str]:
    """Start ``tactile-force ARGS``, wait until it starts loading the package, then ``delay_s``
    more, send ``sig``; (exit code, stderr). The code is None when the process ended before
    the signal could be sent."""
    proc = subprocess.Popen(cli_argv(*args), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + timeout_s
        while not _package_loading(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.001)
        if delay_s:
            time.sleep(delay_s)
        if proc.poll() is not None:
            return None, proc.communicate()[1]
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=timeout_s)
        return proc.returncode, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def early_signal_verdict(args: list[str], sig: int, delay_s: float) -> Verdict:
    """Exit 128 + the signal, one line, no traceback, whatever the moment."""
    if not Path("/proc/self/maps").exists():
        return Verdict(Outcome.ACCEPTED, "not run: needs Linux /proc to see the package start loading")
    rc, err = signal_at_start(args, sig, delay_s)
    name = signal.Signals(sig).name
    if rc is None:
        return Verdict(Outcome.TRACEBACK, f"ended before {name} at +{delay_s:g} s: {err[-200:]}")
    if "Traceback" in err or rc != 128 + int(sig):
        return Verdict(Outcome.TRACEBACK, f"{name} at +{delay_s:g} s: exit {rc}: {err.strip()[-240:]}")
    return Verdict(Outcome.CLEAR, f"{name} at +{delay_s:g} s: exit {rc}: {err.strip()[-120:]}")


#: verbs that run well past the early moments (no data needed)
def early_signal_verbs(folder: Path) -> list[tuple[str, list[str]]]:
    return [("bench", ["bench", "--out", str(folder / "bench"), "--frames", "200"]),
            ("run", ["run", "--source", "virtual", "--max-frames", "100000"])]


def early_signal_cases(folder: Path, examples: int) -> Cases:
    cases: list[tuple[str, Callable[[], Verdict]]] = []
    for verb, args in early_signal_verbs(folder):
        for delay in EARLY_DELAYS:
            cases.append((f"{verb}, SIGINT", lambda a=args, d=delay: early_signal_verdict(a, signal.SIGINT, d)))
        for delay in (0.0, 0.1):
            cases.append((f"{verb}, SIGTERM", lambda a=args, d=delay: early_signal_verdict(a, signal.SIGTERM, d)))
    return cases, "delays counted from the moment the process starts loading the package"


CATEGORIES: list[tuple[str, str, Callable[[Path, int], Cases]]] = [
    ("early_signals", "signals at the CLI's first moments (SIGINT 0-0.3 s, SIGTERM, into bench and run)",
     early_signal_cases),
]
