"""Robustness cases of a runtime's parts and of the waits before a frame (the suite's categories
"runtime parts" and "warm-up waits"; run by :func:`benchmarks.robustness.run_catalogue`).

- one gate, one source or one depth stage given to two sensors, and a source lacking
  ``read`` or ``close``: ``ForceRuntime`` refuses it when built, naming both sensors or the
  missing member (built and stepped: SILENT_WRONG, a shared gate judges one sensor's frame
  against the other's background);
- a source stamping its frames with another clock than the runtime's (the wall clock, a
  camera clock 0.3 s ahead), with warm-ups forced on: the first frame is refused (a
  ``SourceError`` naming the sensor and the clock, or an ``invalid_input`` reading saying so)
  within seconds (a rest planned from such stamps
  was years long: HANG).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable

import numpy as np

from .harness.cases import Outcome, Verdict, accepted, refusal, with_timeout

Case = tuple[str, Callable[[], Verdict]]


def _model():
    from tactile_force.edge import OnnxForceModel, default_bundle_path

    return OnnxForceModel(default_bundle_path(), threads=1)


def _built(make: Callable[[], list], names: tuple[str, ...]) -> Verdict:
    """Build a runtime over ``make()``'s sensors: refused naming ``names`` is right."""
    from tactile_force.edge.runtime import ForceRuntime

    model = _model()
    try:
        rt = ForceRuntime(make(), model, owns_model=False)
    except Exception as exc:  # noqa: BLE001 - classified
        return refusal(exc, True, names=names)
    finally:
        model.close()
    rt.close()
    return accepted(True, "built a runtime whose sensors share a part")


def _virtual(seed: int):
    from tactile_force.edge import VirtualDigitSource

    return VirtualDigitSource(seed=seed, n_grasps=1)


def part_cases() -> list[Case]:
    from tactile_force.edge import ContactGate, Sensor

    def shared_gate() -> list:
        g = ContactGate()
        return [Sensor("a", _virtual(0), g), Sensor("b", _virtual(1), g)]

    def copied_gate() -> list:
        g = ContactGate()
        return [Sensor("a", _virtual(0), g), Sensor("b", _virtual(1), copy.copy(g))]

    def shared_source() -> list:
        src = _virtual(0)
        return [Sensor("a", src, ContactGate()), Sensor("b", src, ContactGate())]

    class NoClose:
        def read(self):
            return None

    class NoRead:
        def close(self) -> None:
            pass

    def lacking(source: object, member: str) -> Verdict:
        try:
            Sensor("a", source, ContactGate())  # type: ignore[arg-type]
        except Exception as exc:  # noqa: BLE001 - classified
            return refusal(exc, True, names=(member,))
        return accepted(True, f"a Sensor over a source without {member}")

    return [
        ("one ContactGate under two sensors", lambda: _built(shared_gate, ("'a'", "'b'", "gate"))),
        ("a shallow copy of a gate (its state shared) under two sensors",
         lambda: _built(copied_gate, ("'a'", "'b'"))),
        ("one source under two sensors", lambda: _built(shared_source, ("'a'", "'b'", "source"))),
        ("a source without close()", lambda: lacking(NoClose(), "close")),
        ("a source without read()", lambda: lacking(NoRead(), "read")),
    ]


class _OtherClock:
    """A fake camera (the hardware boundary): frames at 60 fps stamped ``offset_ns`` from the
    monotonic clock, or with the wall clock."""

    def __init__(self, frames: np.ndarray, wall: bool, offset_ns: int = 0, n: int = 12) -> None:
        self.frames, self.wall, self.offset, self.n, self.i = frames, wall, offset_ns, n, 0

    def read(self):
        from tactile_force.edge.frames import TimedFrame

        if self.i >= self.n:
            return None
        time.sleep(1 / 60)
        now = time.time_ns() if self.wall else time.monotonic_ns() + self.offset
        tf = TimedFrame(self.frames[self.i % len(self.frames)], now, self.i, arrival_ns=now)
        self.i += 1
        return tf

    def close(self) -> None:
        pass


def _stamped(wall: bool, offset_ns: int = 0) -> Verdict:
    from tactile_force.edge import ContactGate, Flags, Sensor
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions

    from .harness.frames import contact_frames

    pool = contact_frames(4)
    gate = ContactGate()
    gate.capture_background(pool.background)
    model = _model()
    rt = ForceRuntime([Sensor("cam", _OtherClock(pool.rgb, wall, offset_ns), gate)], model,
                      RuntimeOptions(prewarm=True))
    try:
        readings = [r for _ in range(20) for r in rt.step()]
    except Exception as exc:  # noqa: BLE001 - classified: the stamp refused at the first frame
        return refusal(exc, True, names=("cam", "clock"))
    finally:
        rt.close()
    bad = [r for r in readings if r.flags & Flags.INVALID_INPUT and "clock" in r.detail]
    if bad:
        return Verdict(Outcome.CLEAR, bad[0].detail[:200])
    return accepted(True, f"{len(readings)} readings from stamps on another clock")


def wait_cases() -> list[Case]:
    return [
        ("a source stamping the wall clock (warm-ups on)", lambda: with_timeout(lambda: _stamped(True), 20.0)),
        ("a camera clock 0.3 s ahead (warm-ups on)",
         lambda: with_timeout(lambda: _stamped(False, 300_000_000), 20.0)),
    ]
