"""The bounds of numeric arguments, one definition each: a frame rate, a count of readings
held in memory, threads, a seed, a time budget. A bound is a
:class:`~tactile_force.edge.typed_json.Check`, used three ways so the three agree:

- on an options dataclass field: ``field(default=600, metadata={METADATA_KEY: WINDOW})``
  (or ``metadata=as_metadata(WINDOW)``);
- in a constructor: ``expect(fps, float, "ReplayFolderSource.fps", **bounds(FPS))``;
- on a CLI flag: ``type=within(float, FPS)`` (:mod:`tactile_force.edge.cli.args`).

The bounds are physical (a sensor's frame rate) or keep memory and arithmetic sane (a window
of readings held in memory, a period that must fit in nanoseconds), never a preference.
"""

from __future__ import annotations

from typing import Any

from .typed_json import METADATA_KEY, Check

#: frames per second: a frame every 100 s at the slowest (a period of 1e-300 s overflows), 10 kHz at the fastest
MIN_FPS, MAX_FPS = 0.01, 10_000.0
FPS = Check(ge=MIN_FPS, le=MAX_FPS)
#: readings measured and held in memory at once (a bench run, a latency window): 10 million, ~80 MB of doubles
MAX_READINGS = 10_000_000
READINGS = Check(ge=1, le=MAX_READINGS)
#: a rolling latency window (frames kept for p50 / p99)
WINDOW = READINGS
#: readings a run or a recording produces before it stops (not held in memory)
MAX_FRAME_COUNT = 10**12
FRAME_COUNT = Check(ge=1, le=MAX_FRAME_COUNT)
#: ONNX Runtime / OpenCV threads
MAX_THREADS = 1024
THREADS = Check(ge=1, le=MAX_THREADS)
#: random seeds (numpy's SeedSequence takes any integer >= 0; 32 bits are portable)
SEED = Check(ge=0, le=2**32 - 1)
#: a latency budget in milliseconds: 1e9 (11.6 days) is "no budget" in effect
BUDGET_MS = Check(gt=0, le=1e9)
#: a runtime's per-frame deadline in milliseconds: 1e9 (11.6 days) is "no deadline" in effect
DEADLINE_MS = Check(gt=0, le=1e9)
#: a pause in seconds: up to a day
PAUSE_S = Check(ge=0, le=86_400)
#: a share of samples
FRACTION = Check(ge=0, le=1)
#: a force in newtons (peak forces of virtual grasps, a reference scale's reading)
FORCE_N = Check(ge=0, le=1000.0)
#: grasps a virtual DIGIT plays (its plan of frames is made up front: ~180 entries a grasp at 60 fps)
GRASPS = Check(ge=1, le=10_000)
#: a lead-in or other span of simulated time in seconds: up to an hour
SPAN_S = Check(ge=0, le=3600.0)
#: a count of grasps, samples, epochs or configurations: up to 10 million
COUNT = Check(ge=1, le=10_000_000)


def bounds(chk: Check) -> dict[str, Any]:
    """The ``gt`` / ``ge`` / ``lt`` / ``le`` of ``chk`` as keyword arguments of
    :func:`tactile_force.edge.checks.expect`."""
    return {k: getattr(chk, k) for k in ("gt", "ge", "lt", "le")}


def as_metadata(chk: Check) -> dict[str, Check]:
    """``chk`` as dataclass field metadata (what :func:`tactile_force.edge.typed_json.check` returns)."""
    return {METADATA_KEY: chk}
