"""Record tactile frames labelled with a reference scale's force, in the authors' layout.

Each sample is written by :class:`~tactile_force.edge.dataset.AuthorsDatasetWriter`, file
by file atomically with the force file last, so a crash or unplug loses at most the frame
in flight. Ctrl-C / SIGTERM finish the sample in flight and stop cleanly. A frame whose
label never landed (power cut, SIGKILL) is removed when recording resumes into the folder.
"""

from __future__ import annotations

import logging
import re
import signal
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from ..edge.dataset import AuthorsDatasetWriter
from ..edge.errors import SourceError
from ..edge.frames import FrameSource, check_frame
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


def prepare_output(root: Path) -> tuple[int, list[int]]:
    """Make ``root`` ready for appending: remove temp files and frames without a label.

    Returns (next free sample id, ids of unlabelled frames removed).
    """
    images, forces, depth = root / "images", root / "forces", root / "filt_img_depth"
    for folder in (images, forces, depth):
        if folder.is_dir():
            for tmp in folder.glob(".*.tmp"):
                tmp.unlink(missing_ok=True)
    img_ids = {int(m.group(1)) for p in images.glob("*.png") if (m := re.fullmatch(r"(\d+)\.png", p.name))} \
        if images.is_dir() else set()
    force_ids = {int(m.group(1)) for p in forces.glob("force_*.txt")
                 if (m := re.fullmatch(r"force_(\d+)\.txt", p.name))} if forces.is_dir() else set()
    removed = sorted(img_ids - force_ids)
    for n in removed:
        (images / f"{n}.png").unlink(missing_ok=True)
        (depth / f"depth_img_{n}.png").unlink(missing_ok=True)
    used = force_ids | (img_ids - set(removed))
    return (max(used) + 1 if used else 0), removed


class _StopFlag:
    """SIGINT/SIGTERM set a flag (main thread only) instead of raising mid-write."""

    def __init__(self, enabled: bool) -> None:
        self.set = False
        self._old: dict[int, object] = {}
        self._enabled = enabled and threading.current_thread() is threading.main_thread()

    def __enter__(self) -> "_StopFlag":
        if self._enabled:
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum, frame) -> None:
        self.set = True

    def __exit__(self, *exc) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)


def record(source: FrameSource, reference: ForceReference, options: RecordOptions) -> RecordResult:
    """Pair each frame of ``source`` with the newest reference force and write it to ``options.out``."""
    out = Path(options.out)
    out.mkdir(parents=True, exist_ok=True)
    start, removed = prepare_output(out)
    if removed:
        log.warning("%s: removed %d frame(s) without a label left by an interrupted recording: %s",
                    out, len(removed), removed)
    result = RecordResult(out=out, removed_unlabelled=removed)
    skip = result.skipped
    with AuthorsDatasetWriter(out, start_id=start) as writer, _StopFlag(options.handle_signals) as stop:
        seen = 0
        while True:
            if stop.set:
                result.stopped_by = "interrupted"
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
            if reason:
                skip[reason] = skip.get(reason, 0) + 1
                continue
            frame = check_frame(item.frame, name=f"frame {item.index}")
            n = writer.write(frame, ref.force_n, meta={
                "timestamp_ns": item.timestamp_ns, "frame_index": item.index,
                "sensor": item.meta.get("sensor", getattr(source, "name", "")),
                "scale_status": ref.status.name.lower(), "scale_value": ref.value, "scale_unit": ref.unit,
                "scale_timestamp_ns": ref.timestamp_ns})
            result.written.append(n)
    return result


def _reject(ref: ScaleReading | None, options: RecordOptions) -> str:
    if ref is None:
        return "no scale reading"
    if not ref.valid:
        return f"scale {ref.status.name.lower()}"
    if options.stable_only and not ref.stable:
        return "scale in motion"
    if options.min_force_n is not None and ref.force_n < options.min_force_n:
        return "below min_force_n"
    return ""
