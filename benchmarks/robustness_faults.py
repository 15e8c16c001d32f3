"""Robustness categories of faults while recording and replaying: kill -9 at each phase of a sample,
truncated files, a full disk and a replay folder that vanishes (benchmarks/robustness.py runs them)."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .harness.cases import (
    Outcome,
    Verdict,
    cli_verdict,
    make_dataset,
    refusal,
    run_cli,
    with_timeout,
    worst,
)
from .harness.paths import require_repo
from .robustness_table import values

REPO = require_repo("the robustness suite (its workers are in tests/robustness)")
KILL_WORKER = REPO / "tests" / "robustness" / "record_kill_worker.py"


# =============================================================================== record faults
KILL_PHASES = tuple(values("kill_phases"))
KILL_AFTER = 3  # complete samples before the kill


def probe_kill(folder: Path, phase: str) -> Verdict:
    """kill -9 of a recording at ``phase`` of sample KILL_AFTER; then resume: every complete
    sample must still read, the dataset must load, and recording must continue after it."""
    from tactile_force.edge.data.dataset import AuthorsDataset
    from tactile_force.firmware_bridge.recorder import RecordOptions, record

    out = folder / f"kill_{phase}"
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.run([sys.executable, str(KILL_WORKER), str(out), phase, str(KILL_AFTER)], env=env,
                          capture_output=True, text=True, timeout=120)
    if proc.returncode != -signal.SIGKILL:
        return Verdict(Outcome.TRACEBACK, f"{phase}: worker exit {proc.returncode}: {proc.stderr[-300:]}")
    complete = KILL_AFTER + (1 if phase == "force_done" else 0)
    res = record(NoiseFrames(seed=99), FixedScale(2.5), RecordOptions(out=out, max_samples=1, handle_signals=False))
    try:
        ds = AuthorsDataset(out)
        samples = list(ds)
    except BaseException as exc:  # noqa: BLE001
        return Verdict(Outcome.TRACEBACK, f"{phase}: unreadable after resume: {exc}")
    if len(samples) < complete + 1:
        return Verdict(Outcome.DATA_LOST, f"{phase}: {len(samples)} samples after resume, expected {complete + 1}")
    if len(samples) > complete + 1 or res.written != [complete]:
        return Verdict(Outcome.SILENT_WRONG, f"{phase}: {len(samples)} samples, resumed at {res.written}")
    if sorted(ds.meta) != [s.id for s in samples]:
        return Verdict(Outcome.SILENT_WRONG,
                       f"{phase}: meta ids {sorted(ds.meta)} vs samples {[s.id for s in samples]}")
    repairs = getattr(res, "repairs", None)
    changed = bool(repairs[0].changed) if repairs else bool(res.removed_unlabelled)
    return Verdict(Outcome.CLEAR if changed else Outcome.ACCEPTED,
                   f"{phase}: {complete} complete samples kept"
                   + (f"; repaired: {repairs[0].describe()}" if repairs else ""))


def probe_truncation(folder: Path, cut: int) -> Verdict:
    """A power cut truncates meta.jsonl ``cut`` bytes into its last line: the reader names the
    file and line until repaired; ``record --repair`` keeps every complete sample."""
    from tactile_force.edge.data.dataset import AuthorsDataset

    src = folder / "trunc_src"
    if not src.is_dir():
        make_dataset(src, n=4)
    out = folder / "trunc"
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(src, out)
    meta = out / "meta.jsonl"
    data = meta.read_bytes()
    last = data.rstrip(b"\n").rfind(b"\n") + 1
    meta.write_bytes(data[:last + cut])
    verdicts = []
    partial = 0 < cut < len(data) - last - 1
    if partial:
        try:
            AuthorsDataset(out)
            verdicts.append(Verdict(Outcome.SILENT_WRONG, f"cut {cut}: a cut-short line read without complaint"))
        except BaseException as exc:  # noqa: BLE001
            verdicts.append(refusal(exc, True, names=("meta.jsonl", "line 4", "--repair")))
    verdicts.append(cli_verdict(["record", "--repair", str(out)], {0}, False))
    try:
        samples = list(AuthorsDataset(out))
    except BaseException as exc:  # noqa: BLE001
        return worst([*verdicts, Verdict(Outcome.DATA_LOST, f"cut {cut}: unreadable after repair: {exc}")])
    if len(samples) != 4:
        verdicts.append(Verdict(Outcome.DATA_LOST, f"cut {cut}: {len(samples)} of 4 samples after repair"))
    w = worst(verdicts)
    return Verdict(w.outcome, f"cut {cut}: {w.detail}")


class NoiseFrames:
    """A frame source of incompressible random frames (fills a disk fast), forever."""

    name = "noise"

    def __init__(self, seed: int = 0) -> None:
        from tactile_force.edge.frames import SourceStats

        self.rng = np.random.default_rng(seed)
        self.i = 0
        self.stats = SourceStats()

    def read(self):
        from tactile_force.edge.frames import TimedFrame

        self.i += 1
        return TimedFrame(self.rng.integers(0, 256, (320, 240, 3), dtype=np.uint8), self.i * 1000, self.i)


class FixedScale:
    """The newest reading of a HID POS scale, decoded from a real report by parse_scale_report."""

    def __init__(self, force_n: float) -> None:
        self.grams = int(round(force_n / 9.80665 * 1000))

    def read(self):
        from tactile_force.firmware_bridge.hid_scale import parse_scale_report

        g = self.grams
        return parse_scale_report([0x03, 0x04, 0x02, 0x00, g & 0xFF, (g >> 8) & 0xFF])


@contextlib.contextmanager
def small_filesystem(folder: Path, size_kib: int = 1536) -> Iterator[tuple[Path, str]]:
    """A small real filesystem (tmpfs, needs root) at ``folder``; else the same folder with every
    write past ``size_kib`` failing with ENOSPC (a patched AuthorsDatasetWriter). Yields (path, method)."""
    folder.mkdir(parents=True, exist_ok=True)
    mounted = False
    if hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("mount"):
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kib}k", "tmpfs", str(folder)],
                           capture_output=True, text=True)
        mounted = r.returncode == 0
    if mounted:
        try:
            yield folder, f"tmpfs of {size_kib} KiB (mount -t tmpfs)"
        finally:
            subprocess.run(["umount", str(folder)], capture_output=True)
        return
    import errno

    from tactile_force.edge.data import dataset as ds_mod

    budget = {"left": size_kib * 1024}
    orig_atomic = ds_mod.AuthorsDatasetWriter._atomic_write

    def atomic(path: Path, data: bytes) -> None:
        if len(data) > budget["left"]:
            tmp = path.with_name(f".{path.name}.tmp")
            tmp.write_bytes(data[:budget["left"]])
            budget["left"] = 0
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
        budget["left"] -= len(data)
        orig_atomic(path, data)

    ds_mod.AuthorsDatasetWriter._atomic_write = staticmethod(atomic)
    try:
        yield folder, f"simulated: writes past {size_kib} KiB raise ENOSPC (not root: no tmpfs)"
    finally:
        ds_mod.AuthorsDatasetWriter._atomic_write = staticmethod(orig_atomic)


def probe_disk_full(folder: Path) -> tuple[Verdict, str]:
    """Record onto a small filesystem until it is full, through the CLI (DIGIT and HID scale
    faked at the hardware boundary): exit 1, summary printed, every sample written readable."""
    from tactile_force.edge.data.dataset import AuthorsDataset

    with small_filesystem(folder / "small_fs") as (fs, method):
        out = fs / "ds"
        rc, stdout, stderr = _record_cli_with_fakes(["record", "--sensor", "0", "--out", str(out)])
        verdicts = []
        m = re.search(r"wrote (\d+) sample", stdout)
        if "Traceback" in stdout + stderr:
            verdicts.append(Verdict(Outcome.TRACEBACK, stderr[-300:]))
        elif rc == 0 or "disk full" not in stderr or not m:
            verdicts.append(Verdict(Outcome.SILENT_WRONG,
                                    f"exit {rc}; stdout {stdout[-200:]!r}; stderr {stderr[-200:]!r}"))
        written = int(m.group(1)) if m else None  # no summary: judged above, not as data lost
        try:
            n = len(list(AuthorsDataset(out)))
            leftovers = [p.name for p in out.rglob(".*.tmp")]
            if n < 1 or (written is not None and n != written):
                verdicts.append(Verdict(Outcome.DATA_LOST, f"{n} samples read back, summary says {written}"))
            elif leftovers:
                verdicts.append(Verdict(Outcome.SILENT_WRONG, f"temp files left: {leftovers}"))
        except BaseException as exc:  # noqa: BLE001
            verdicts.append(Verdict(Outcome.DATA_LOST, f"unreadable after disk full: {exc}"))
        if not verdicts:
            verdicts.append(Verdict(Outcome.CLEAR, f"exit {rc}, {written} samples kept: {stderr.strip()[:160]}"))
        return worst(verdicts), method


def _record_cli_with_fakes(argv: list[str]) -> tuple[int, str, str]:
    """``tactile-force record`` with DigitSource and HidScale replaced by fakes (hardware boundary)."""
    from tactile_force.firmware_bridge import digit, hid_scale

    class FakeDigit(NoiseFrames):
        def __init__(self, options) -> None:
            super().__init__(seed=1)
            self.node = "/dev/video-fake"

        def __enter__(self):
            return self

        def __exit__(self, *exc) -> None:
            pass

    class FakeScaleHandle(FixedScale):
        name = "fake HID scale"

        def close(self) -> None:
            pass

    old_src, old_open = digit.DigitSource, hid_scale.HidScale.open
    digit.DigitSource = FakeDigit
    hid_scale.HidScale.open = classmethod(lambda cls, options=None: FakeScaleHandle(3.0))
    try:
        return run_cli(argv)
    finally:
        digit.DigitSource = old_src
        hid_scale.HidScale.open = old_open


def probe_replay_vanish(folder: Path, paced: bool) -> Verdict:
    """A replay folder deleted mid-run: the next read raises SourceError (never idles)."""
    from tactile_force.edge.sources import ReplayFolderSource

    root = folder / f"vanish_{paced}"
    shutil.rmtree(root, ignore_errors=True)
    make_dataset(root, n=10)

    def run() -> Verdict:
        src = ReplayFolderSource(root, fps=200.0 if paced else None)
        for _ in range(3):
            if src.read() is None:
                return Verdict(Outcome.SILENT_WRONG, "ended early")
        shutil.rmtree(root)
        try:
            got = src.read()
        except BaseException as exc:  # noqa: BLE001
            return refusal(exc, True, names=("disappeared",))
        return Verdict(Outcome.SILENT_WRONG, f"read after deletion returned {type(got).__name__}, "
                                             f"{src.stats.corrupt} counted corrupt")

    return with_timeout(run, 20.0)
