"""Reading writers: stdout lines, a one-line live status, CSV and JSONL files.

File writers flush after every reading, so whatever was written survives a crash or a
sensor failure; ``fsync=True`` also forces it to the disk (slower).
"""

from __future__ import annotations

import csv
import json
import math
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TextIO

from ..checks import expect
from ..errors import ArgumentTypeError
from ..reading import ForceReading, IntervalState

FIELDS = list(ForceReading("", 0, 0, 0.0).as_dict())


def _json_value(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None  # JSON has no NaN; null = not measured
    return v


def format_interval(r: ForceReading) -> str:
    """The reading's interval for humans: '[4.41, 5.99] N', '[14.2, inf) N' when open above
    (saturated), '[?]' when unknown (NaN bounds: no estimate, or none the bundle can state)."""
    if r.interval is IntervalState.UNKNOWN or math.isnan(r.force_low_n):
        return "[  ?  ]"
    if r.interval is IntervalState.OPEN_ABOVE or math.isinf(r.force_high_n):
        return f"[{r.force_low_n:.2f}, inf) N"
    return f"[{r.force_low_n:.2f}, {r.force_high_n:.2f}] N"


def format_reading(r: ForceReading) -> str:
    """One human line: sensor, frame, force and its interval, truth, flags, total latency."""
    force = "   --  " if math.isnan(r.force_n) else f"{r.force_n:6.2f} N {format_interval(r)}"
    truth = "" if r.truth_n is None else f"  truth {r.truth_n:6.2f} N"
    flags = ",".join(r.flags.names()) or "ok"
    return f"{r.sensor:>6} #{r.frame_index:<6d} {force}{truth}  [{flags}]  {r.latency.total_ms:6.2f} ms"


class _FileWriter:
    def __init__(self, path: str | os.PathLike, fsync: bool = False) -> None:
        owner = type(self).__name__
        expect(path, (str, os.PathLike), f"{owner}.path", "a file path", nonempty=True)
        expect(fsync, bool, f"{owner}.fsync")
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh: TextIO = open(self.path, "w", newline="")
        self._fsync = fsync

    def _flush(self) -> None:
        self._fh.flush()
        if self._fsync:
            os.fsync(self._fh.fileno())

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class CsvWriter(_FileWriter):
    """CSV with a header (ForceReading.as_dict keys); one row per reading, flushed."""

    def __init__(self, path: str | os.PathLike, fsync: bool = False) -> None:
        super().__init__(path, fsync)
        self._w = csv.DictWriter(self._fh, fieldnames=FIELDS)
        self._w.writeheader()
        self._flush()

    def write(self, r: ForceReading) -> None:
        self._w.writerow(r.as_dict())
        self._flush()


class JsonlWriter(_FileWriter):
    """One JSON object per line per reading (NaN and inf written as null: ``interval`` says
    which, 'open_above' for an infinite ``force_high_n``), flushed."""

    def write(self, r: ForceReading) -> None:
        self._fh.write(json.dumps({k: _json_value(v) for k, v in r.as_dict().items()}) + "\n")
        self._flush()


class StdoutWriter:
    """Readings on stdout: every reading as a line, or (``live=True``) one status line
    rewritten in place with the newest force, flags and the rolling p99 from ``p99_ms()``."""

    def __init__(self, live: bool = False, stream: TextIO | None = None, p99_ms=None, every: int = 1) -> None:
        expect(live, bool, "StdoutWriter.live")
        if stream is not None and not callable(getattr(stream, "write", None)):
            raise ArgumentTypeError(f"StdoutWriter.stream={stream!r}: expected a text stream with write() "
                                    f"(e.g. sys.stderr) or None (stdout), got {type(stream).__name__}")
        expect(p99_ms, Callable | None, "StdoutWriter.p99_ms", "a callable returning the p99 in ms, or None")
        expect(every, int, "StdoutWriter.every", "an integer >= 1 (readings per status line update)", ge=1)
        self.stream = stream or sys.stdout
        self.live = live
        self._p99 = p99_ms
        self._every = max(1, every)
        self._n = 0

    def write(self, r: ForceReading) -> None:
        self._n += 1
        if not self.live:
            self.stream.write(format_reading(r) + "\n")
            self.stream.flush()
            return
        if self._n % self._every:
            return
        p99 = f"  p99 {self._p99():6.2f} ms" if self._p99 is not None else ""
        detail = f"  {r.detail}" if r.detail else ""  # e.g. 'learning background'
        self.stream.write("\r" + format_reading(r) + p99 + detail + "   ")
        self.stream.flush()

    def close(self) -> None:
        if self.live and self._n:
            self.stream.write("\n")
            self.stream.flush()
