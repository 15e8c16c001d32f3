"""Subprocess for the kill -9 tests: records noise frames labelled by a scale (HID report
decoded by the real parser) and SIGKILLs itself at one write phase of sample K.

argv: OUT_DIR PHASE K, PHASE one of benchmarks.robustness.KILL_PHASES:
image_tmp (half the image's temp file written), image_done (image renamed in place),
meta_partial (half the meta.jsonl line flushed), meta_done (meta line flushed),
force_tmp (label's temp file written, not renamed), force_done (label renamed: sample complete).
"""

import builtins
import os
import signal
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.robustness import FixedScale, NoiseFrames, use_package_root  # noqa: E402

if os.environ.get("TF_PACKAGE_ROOT"):  # the baseline run against an older commit
    use_package_root(os.environ["TF_PACKAGE_ROOT"])
from tactile_force.edge.data import dataset as ds_mod  # noqa: E402
from tactile_force.firmware_bridge.recorder import RecordOptions, record  # noqa: E402

out, phase, k = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3])
state = {"sample": 0}


def die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


orig_atomic = ds_mod.AuthorsDatasetWriter._atomic_write


def atomic(path: Path, data: bytes) -> None:
    kind = path.parent.name
    target = state["sample"] == k
    if target and kind == "images" and phase == "image_tmp":
        path.with_name(f".{path.name}.tmp").write_bytes(data[: len(data) // 2])
        die()
    if target and kind == "forces" and phase == "force_tmp":
        path.with_name(f".{path.name}.tmp").write_bytes(data)
        die()
    orig_atomic(path, data)
    if target and kind == "images" and phase == "image_done":
        die()
    if target and kind == "forces" and phase == "force_done":
        die()
    if kind == "forces":
        state["sample"] += 1


class MetaFile:
    """meta.jsonl opened by the writer, with a kill at the chosen phase."""

    def __init__(self, fh) -> None:
        self.fh = fh

    def write(self, text: str) -> int:
        if state["sample"] == k and phase == "meta_partial":
            self.fh.write(text[: len(text) // 2])
            self.fh.flush()
            die()
        return self.fh.write(text)

    def flush(self) -> None:
        self.fh.flush()
        if state["sample"] == k and phase == "meta_done":
            die()

    def fileno(self) -> int:
        return self.fh.fileno()

    def close(self) -> None:
        self.fh.close()


ds_mod.AuthorsDatasetWriter._atomic_write = staticmethod(atomic)


def open_meta(file, *a, **kw):
    fh = builtins.open(file, *a, **kw)
    return MetaFile(fh) if Path(file).name == "meta.jsonl" else fh


ds_mod.open = open_meta  # a module global shadows the builtin inside tactile_force.edge.data.dataset

result = record(NoiseFrames(), FixedScale(1.5), RecordOptions(out=out, max_samples=k + 5, handle_signals=False))
print(f"not killed: wrote {result.written}", flush=True)
sys.exit(3)
