"""Subprocess for the interruption tests: records real DIGIT frames (looped) labelled by a
fake HID scale until killed. argv: DATASET_DIR OUT_DIR."""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tactile_force.edge.data.dataset import AuthorsDataset  # noqa: E402
from tactile_force.edge.frames import FrameSource, TimedFrame  # noqa: E402
from tactile_force.firmware_bridge import HidScale, RecordOptions, record  # noqa: E402

from bridge.fakes import FakeHidDevice  # noqa: E402


def scale_report(grams: int) -> list[int]:
    """HID POS data report: id 3, stable, grams, exponent 0, little-endian weight."""
    return [0x03, 0x04, 0x02, 0x00, grams & 0xFF, grams >> 8]


class LoopedFrames(FrameSource):
    """Real frames from a labelled folder, forever, ``period_s`` apart."""

    def __init__(self, root: str, period_s: float) -> None:
        super().__init__()
        self.frames = [s.frame for s in AuthorsDataset(root)]
        self.period_s, self.i, self.name = period_s, 0, "looped"

    def read(self) -> TimedFrame:
        time.sleep(self.period_s)
        f = TimedFrame(self.frames[self.i % len(self.frames)], time.monotonic_ns(), self.i)
        self.i += 1
        return f


if __name__ == "__main__":
    src = LoopedFrames(sys.argv[1], 0.03)
    scale = HidScale(FakeHidDevice([scale_report(100 * (k + 1)) for k in range(10_000)]))
    result = record(src, scale, RecordOptions(out=Path(sys.argv[2])))
    print(f"written {len(result.written)} stopped {result.stopped_by}", flush=True)
