"""Shared test helpers: where the real sensor data lives, and a skip when it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from tactile_force.edge.frames import FrameSource, TimedFrame

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("TACTILE_FORCE_SHARED_DATA", REPO.parent / "shared" / "data"))

#: Cyclone DDS on the loopback interface only (lo, no multicast, peer 127.0.0.1), set before any
#: DDS participant exists in the test process; .ci/run exports the same file.
CYCLONEDDS_LOOPBACK = REPO / "tests" / "cyclonedds_loopback.xml"
os.environ["CYCLONEDDS_URI"] = CYCLONEDDS_LOOPBACK.as_uri()


#: What the shared data is, where it comes from and how to point to it: the one reason every
#: test that needs it gives when it is absent.
SHARED_DATA_ABOUT = (
    "it holds real sensor data kept outside the repository (real DIGIT frames with forces and depth images "
    "from AUROVA-LAB, DIGIT backgrounds and ball presses, GelSight Mini and Wedge data; its README.md gives "
    "each file's source and licence); by default it is shared/data in the folder that holds the checkout: "
    "set TACTILE_FORCE_SHARED_DATA to the data folder when it is elsewhere"
)


def shared_data(*parts: str) -> Path:
    """Path under the shared data folder (``SHARED_DATA``); skips the test, saying what the data
    is and where it comes from, when it is absent."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        where = (f"the shared data folder {SHARED_DATA} is missing" if not SHARED_DATA.is_dir()
                 else f"{p} is missing from the shared data folder")
        pytest.skip(f"{where}: {SHARED_DATA_ABOUT}")
    return p


class ListSource(FrameSource):
    """A finite source over in-memory frames, each read once, with its true force (N; None =
    unknown); ``closed`` tells whether the runtime closed it. Timestamps are 0, the index is the
    frame's position."""

    name = "memory"

    def __init__(self, frames, truth=None) -> None:
        super().__init__()
        self.frames = list(frames)
        truth = [None] * len(self.frames) if truth is None else truth
        self.truth = [None if t is None else float(t) for t in truth]
        self.closed = False

    def read(self):
        i = self.stats.frames
        if i >= len(self.frames):
            return None
        self.stats.frames += 1
        return TimedFrame(self.frames[i], 0, i, self.truth[i])

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def aurova_dir() -> Path:
    """The 11 real DIGIT frames with forces (authors' layout)."""
    return shared_data("aurova_digit_grasp")


@pytest.fixture
def portraits(aurova_dir):
    """The first three real AUROVA DIGIT frames (320x240x3 uint8 BGR, portrait)."""
    from tactile_force.edge import AuthorsDataset

    data = AuthorsDataset(aurova_dir)
    return [data[i].frame for i in range(3)]
