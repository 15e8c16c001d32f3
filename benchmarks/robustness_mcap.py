"""Cases for the robustness catalogue (benchmarks/robustness.py): MCAP logs written by a real
``tactile-force run`` stopped by SIGTERM / SIGINT / kill -9, read back by the mcap library's
readers (``data lost`` when a written reading is missing or the log was not finalized)."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from .harness.cases import Outcome, Verdict, worst
from .robustness_inputs import TF_CLI


# ================================================================== MCAP killed
def mcap_forces(path: Path, sequential: bool) -> list[float]:
    """The force of every /tactile/force message of the MCAP log ``path`` (N), read by the mcap
    library's ``NonSeekingReader`` (``sequential``) or ``make_reader``, both with their defaults."""
    from mcap.reader import NonSeekingReader, make_reader
    from tactile_force.edge.outputs.ros2_messages import WrenchStamped

    with open(path, "rb") as fh:
        reader = NonSeekingReader(fh) if sequential else make_reader(fh)
        return [WrenchStamped.deserialize(m.data).wrench.force.z
                for _, ch, m in reader.iter_messages() if ch.topic == "/tactile/force"]


def _csv_count(path: Path) -> int:
    return max(0, len(path.read_text().splitlines()) - 1) if path.is_file() else 0


def mcap_replay(folder: Path) -> Path:
    """198 frames (noise blocks on a flat gel) in the authors' layout: 10 s at --fps 20."""
    import cv2
    from tactile_force.edge.data.dataset import AuthorsDatasetWriter

    root = folder / "mcap_replay"
    rng = np.random.default_rng(3)
    with AuthorsDatasetWriter(root) as w:
        for i in range(198):
            frame = np.full((320, 240, 3), 110, np.uint8)
            if i % 3:
                frame[120:200, 70:170] = rng.integers(60, 200, (80, 100, 3), dtype=np.uint8)
            w.write(cv2.GaussianBlur(frame, (5, 5), 0), 1.0 + i % 9)
    return root


class RunEndedEarly(RuntimeError):
    """The run ended before it could be stopped (``stderr``: what it wrote there)."""

    def __init__(self, stderr: str) -> None:
        super().__init__(f"run ended before the signal: {stderr[-800:]}")
        self.stderr = stderr


def stopped_run(replay: Path, folder: Path, sig: int, after: int = 12,
                timeout_s: float = 60) -> tuple[subprocess.CompletedProcess, Path, Path]:
    """A real ``tactile-force run --source replay --fps 20 --out r.csv --out r.mcap`` into ``folder``,
    sent ``sig`` once its CSV holds ``after`` readings: (the finished process, the CSV, the log).
    Raises :class:`RunEndedEarly` when the run ended before the signal and
    ``subprocess.TimeoutExpired`` when it did not stop within ``timeout_s`` (it is killed)."""
    out_csv, out_mcap = folder / "r.csv", folder / "r.mcap"
    proc = subprocess.Popen([sys.executable, str(TF_CLI), "run", "--source", str(replay), "--fps", "20",
                             "--out", str(out_csv), "--out", str(out_mcap)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        end = time.monotonic() + 120
        while time.monotonic() < end and proc.poll() is None and _csv_count(out_csv) < after:
            time.sleep(0.05)
        if proc.poll() is not None:
            raise RunEndedEarly(proc.stderr.read() if proc.stderr else "")
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=timeout_s)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return subprocess.CompletedProcess(proc.args, proc.returncode, "", err), out_csv, out_mcap


def probe_mcap_signal(folder: Path, replay: Path, sig: int) -> Verdict:
    """A real ``tactile-force run --out r.csv --out r.mcap`` stopped by ``sig`` after 12 readings;
    the mcap library's readers must return every reading the CSV holds (kill -9: at most the one
    in flight fewer), and SIGTERM / SIGINT must leave a finalized file (summary)."""
    name = signal.Signals(sig).name
    d = folder / f"mcap_{name}"
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir(parents=True)
    try:
        done, out_csv, out_mcap = stopped_run(replay, d, sig)
    except RunEndedEarly as exc:
        return Verdict(Outcome.TRACEBACK, f"{name}: run ended before the signal: {exc.stderr[-200:]}")
    except subprocess.TimeoutExpired:
        return Verdict(Outcome.HANG, f"{name}: run did not stop within 60 s")
    err = done.stderr
    written = _csv_count(out_csv)
    verdicts = []
    for sequential in (False, True):
        who = "NonSeekingReader" if sequential else "make_reader"
        try:
            got = len(mcap_forces(out_mcap, sequential))
        except Exception as exc:  # noqa: BLE001 - the library refusing the file is the finding
            verdicts.append(Verdict(Outcome.DATA_LOST, f"{name}: {who} read nothing: {type(exc).__name__}: "
                                                       f"{str(exc)[:120]} ({written} readings written)"))
            continue
        lost = written - got
        allowed = 1 if sig == signal.SIGKILL else 0
        if lost > allowed:
            verdicts.append(Verdict(Outcome.DATA_LOST, f"{name}: {who} read {got} of {written} readings"))
        else:
            verdicts.append(Verdict(Outcome.ACCEPTED, f"{name}: {who} read {got} of {written} readings"))
    if sig != signal.SIGKILL:
        from mcap.reader import make_reader

        try:
            with open(out_mcap, "rb") as fh:
                summary = make_reader(fh).get_summary()
        except Exception as exc:  # noqa: BLE001
            summary = None
            err += f" {type(exc).__name__}: {exc}"
        if summary is None or not summary.chunk_indexes:
            verdicts.append(Verdict(Outcome.DATA_LOST, f"{name}: the log was not finalized (no summary): "
                                                       f"{err[-160:]}"))
    return worst(verdicts)


def mcap_available() -> bool:
    try:
        import cyclonedds  # noqa: F401
        import mcap  # noqa: F401
    except ImportError:
        return False
    return True
