"""Record tactile frames labelled with a reference scale's force, in the authors' layout.

Each sample is written by :class:`~tactile_force.edge.data.dataset.AuthorsDatasetWriter`, file
by file atomically with the force file last, so a crash or unplug loses at most the frame
in flight. Ctrl-C / SIGTERM finish the sample in flight and stop cleanly.

Repair (:func:`repair_dataset`, run when recording resumes into a folder and by
``tactile-force record --repair DIR`` without any hardware): temp files are removed, a
frame whose label never landed (power cut, SIGKILL, full disk) is removed, and a
``meta.jsonl`` whose last line(s) are cut short or belong to such a frame is truncated
after its last complete, labelled line. Truncating needs no free space, so repair also
works on a full disk. A full disk (or any failed write) stops the recording cleanly:
the sample in flight is dropped, every sample written before it stays readable, and
the result says why it stopped.
"""

from __future__ import annotations

import errno
import logging
import os
import re
import signal
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from tactile_force.edge.data.dataset import AuthorsDatasetWriter
from tactile_force.edge.data.labels import LabelError, check_force, complete_meta_prefix
from tactile_force.edge.errors import DatasetError, SourceError
from tactile_force.edge.frames import FrameSource, check_frame

from .hid_scale import ScaleReading

log = logging.getLogger(__name__)


class ForceReference(Protocol):
    """Anything that gives the newest reference reading (e.g. :class:`HidScale`)."""

    def read(self) -> ScaleReading | None: ...


@dataclass
class RecordOptions:
    """out: dataset folder (created; resumed if it holds samples); max_samples: stop after this
    many written (None = until interrupted or the source ends); every_n: keep every n-th frame;
    stable_only: skip frames while the scale reports motion; min_force_n: skip frames whose
    reference force is below this (N; e.g. 0 to drop negative readings, None keeps all)."""

    out: Path
    max_samples: int | None = None
    every_n: int = 1
    stable_only: bool = False
    min_force_n: float | None = None
    handle_signals: bool = True


@dataclass
class RecordResult:
    """What a recording did: sample ids written, frames skipped and why it stopped."""

    out: Path
    written: list[int] = field(default_factory=list)
    skipped: dict[str, int] = field(default_factory=dict)
    removed_unlabelled: list[int] = field(default_factory=list)
    stopped_by: str = ""
    repairs: list[RepairReport] = field(default_factory=list)
    signal: int | None = None  # the signal (SIGINT, SIGTERM) that stopped the recording, if one did

    @property
    def write_failed(self) -> bool:
        """True when the recording stopped because a write failed (disk full, I/O error)."""
        return self.stopped_by.startswith(("disk full", "write failed"))


@dataclass
class RepairReport:
    """What :func:`repair_dataset` changed: unlabelled frame ids removed, temp files removed,
    bytes and lines cut from the end of ``meta.jsonl``, and the next free sample id."""

    root: Path
    next_id: int
    removed_unlabelled: list[int] = field(default_factory=list)
    removed_temp: list[Path] = field(default_factory=list)
    meta_bytes_dropped: int = 0
    meta_lines_dropped: int = 0

    @property
    def changed(self) -> bool:
        return bool(self.removed_unlabelled or self.removed_temp or self.meta_bytes_dropped)

    def describe(self) -> str:
        """One line for a log or the console."""
        if not self.changed:
            return f"{self.root}: nothing to repair; next sample id {self.next_id}"
        parts = []
        if self.removed_unlabelled:
            parts.append(f"removed {len(self.removed_unlabelled)} frame(s) without a label {self.removed_unlabelled}")
        if self.removed_temp:
            parts.append(f"removed {len(self.removed_temp)} temp file(s)")
        if self.meta_bytes_dropped:
            parts.append(f"dropped the last {self.meta_lines_dropped} line(s) of meta.jsonl "
                         f"({self.meta_bytes_dropped} bytes: cut short or of a removed frame)")
        return f"{self.root}: " + "; ".join(parts) + f"; next sample id {self.next_id}"


def repair_dataset(root: str | os.PathLike) -> RepairReport:
    """Make a recording folder consistent after a crash, keeping every complete sample.

    Removes temp files and frames without a label, and truncates ``meta.jsonl`` after its
    last complete line of a labelled sample (see :func:`~tactile_force.edge.data.labels.complete_meta_prefix`).
    Needs no free disk space. DatasetError naming the folder when it cannot be changed.
    """
    root = Path(root)
    images, forces, depth = root / "images", root / "forces", root / "filt_img_depth"
    temps: list[Path] = []
    try:
        for folder in (images, forces, depth):
            if folder.is_dir():
                for tmp in folder.glob(".*.tmp"):
                    tmp.unlink(missing_ok=True)
                    temps.append(tmp)
        img_ids = {int(m.group(1)) for p in images.glob("*.png") if (m := re.fullmatch(r"(\d+)\.png", p.name))} \
            if images.is_dir() else set()
        force_ids = {int(m.group(1)) for p in forces.glob("force_*.txt")
                     if (m := re.fullmatch(r"force_(\d+)\.txt", p.name))} if forces.is_dir() else set()
        removed = sorted(img_ids - force_ids)
        for n in removed:
            (images / f"{n}.png").unlink(missing_ok=True)
            (depth / f"depth_img_{n}.png").unlink(missing_ok=True)
        used = force_ids | (img_ids - set(removed))
        report = RepairReport(root, (max(used) + 1 if used else 0), removed, temps)
        meta = root / "meta.jsonl"
        if meta.is_file():
            data = meta.read_bytes()
            keep = complete_meta_prefix(data, keep_ids=force_ids)
            if keep < len(data):
                with open(meta, "r+b") as fh:
                    fh.truncate(keep)
                    fh.flush()
                    os.fsync(fh.fileno())
                report.meta_bytes_dropped = len(data) - keep
                report.meta_lines_dropped = data[keep:].count(b"\n") + (0 if data.endswith(b"\n") else 1)
    except OSError as exc:
        raise DatasetError(f"{root}: cannot repair the recording ({exc.strerror or exc})") from None
    return report


def prepare_output(root: Path) -> tuple[int, list[int]]:
    """Make ``root`` ready for appending (:func:`repair_dataset`).

    Returns (next free sample id, ids of unlabelled frames removed).
    """
    report = repair_dataset(root)
    return report.next_id, report.removed_unlabelled


class _StopFlag:
    """SIGINT/SIGTERM set a flag (main thread only) instead of raising mid-write."""

    def __init__(self, enabled: bool) -> None:
        self.set = False
        self.signum: int | None = None
        self._old: dict[int, Any] = {}
        self._enabled = enabled and threading.current_thread() is threading.main_thread()

    def __enter__(self) -> _StopFlag:
        if self._enabled:
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum, frame) -> None:
        self.set = True
        self.signum = signum

    def __exit__(self, *exc) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


def record(source: FrameSource, reference: ForceReference, options: RecordOptions) -> RecordResult:
    """Pair each frame of ``source`` with the newest reference force and write it to ``options.out``."""
    out = Path(options.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(f"{out}: cannot create the recording folder ({exc.strerror or exc})") from None
    from tactile_force.edge.files.claim import OutputClaim

    # one recorder per folder: a second one would 'repair' away the first one's sample in flight
    with OutputClaim(out, "record", inside=True):
        return _record_claimed(out, source, reference, options)


def _record_claimed(out: Path, source: FrameSource, reference: ForceReference, options: RecordOptions) -> RecordResult:
    """:func:`record` once ``out`` is claimed."""
    report = repair_dataset(out)
    if report.changed:
        log.warning("repaired what an interrupted recording left: %s", report.describe())
    result = RecordResult(out=out, removed_unlabelled=list(report.removed_unlabelled), repairs=[report])
    try:
        writer = AuthorsDatasetWriter(out, start_id=report.next_id)
    except OSError as exc:
        raise DatasetError(f"{out}: cannot write the recording folder ({exc.strerror or exc})") from None
    try:
        _loop(source, reference, options, writer, result)
    finally:
        try:
            writer.close()
        except OSError as exc:  # the sample in flight's meta line could not be flushed
            if not result.write_failed:
                result.stopped_by = _write_failure(exc)
    if result.write_failed:
        after = repair_dataset(out)  # drop the sample in flight; truncation needs no free space
        result.removed_unlabelled += after.removed_unlabelled
        result.repairs.append(after)
        log.error("%s: recording stopped: %s; %d sample(s) written this run are kept",
                  out, result.stopped_by, len(result.written))
    return result


def _write_failure(exc: OSError) -> str:
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        return f"disk full: {exc.strerror or exc}"
    return f"write failed: {exc.strerror or exc}"


def _loop(source: FrameSource, reference: ForceReference, options: RecordOptions, writer: AuthorsDatasetWriter,
          result: RecordResult) -> None:
    skip = result.skipped
    with _StopFlag(options.handle_signals) as stop:
        seen = 0
        while True:
            if stop.set:
                result.stopped_by = "interrupted"
                result.signal = stop.signum
                break
            if options.max_samples is not None and len(result.written) >= options.max_samples:
                result.stopped_by = "max_samples"
                break
            try:
                item = source.read()
            except SourceError as exc:
                result.stopped_by = f"sensor lost: {exc}"
                break
            if item is None:
                result.stopped_by = "source ended"
                break
            seen += 1
            if (seen - 1) % max(1, options.every_n):
                continue
            try:
                ref = reference.read()
            except SourceError as exc:
                result.stopped_by = f"scale lost: {exc}"
                break
            reason = _reject(ref, options)
            if reason or ref is None:
                skip[reason] = skip.get(reason, 0) + 1
                continue
            frame = check_frame(item.frame, name=f"frame {item.index}")
            try:
                n = writer.write(frame, ref.force_n, meta={
                    "timestamp_ns": item.timestamp_ns, "frame_index": item.index,
                    "sensor": item.meta.get("sensor", getattr(source, "name", "")),
                    "scale_status": ref.status.name.lower(), "scale_value": ref.value, "scale_unit": ref.unit,
                    "scale_timestamp_ns": ref.timestamp_ns})
            except OSError as exc:
                result.stopped_by = _write_failure(exc)
                break
            result.written.append(n)


def _reject(ref: ScaleReading | None, options: RecordOptions) -> str:
    if ref is None:
        return "no scale reading"
    if not ref.valid:
        return f"scale {ref.status.name.lower()}"
    if options.stable_only and not ref.stable:
        return "scale in motion"
    if options.min_force_n is not None and ref.force_n < options.min_force_n:
        return "below min_force_n"
    try:
        check_force(ref.force_n, "scale")
    except LabelError:
        return "force outside the label range"
    return ""
