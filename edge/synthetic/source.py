"""VirtualDigitSource: a FrameSource of simulated grasps at 60 fps with force ground truth.

Each grasp: approach (no contact) -> ramp (smooth rise to the peak force) -> hold (peak with
a small tremor) -> release -> no contact. The stream starts with a longer no-contact lead-in
so a contact gate can learn its background, and the LEDs drift slowly over time.
"""

from __future__ import annotations

import queue
import threading
import time
import weakref

import numpy as np

from ..checks import expect
from ..errors import OptionsError
from ..frames import FrameSource, TimedFrame
from ..limits import FORCE_N, FPS, GRASPS, SEED, SPAN_S, bounds
from .digit import VirtualDigit, VirtualDigitOptions
from .indenters import paper_indenter_names
from .sampling import sample_contact

PHASES = ("approach", "ramp", "hold", "release", "no_contact")


class VirtualDigitSource(FrameSource):
    """Simulated DIGIT grasps as a frame source.

    seed: all randomness (indenters, poses, forces, noise); n_grasps: grasps before the
    stream ends (read() -> None); fps: frame rate (timestamps are exact multiples of
    1/fps from ``start_ns``); peak_n: range of peak forces (N); lead_in_s: no-contact time
    before the first grasp; indenters: names to draw from (default: the paper's 18);
    led_drift: relative amplitude of the slow LED drift; realtime: sleep to pace frames at
    fps; start_ns: timestamp of frame 0 (default: now, monotonic clock); name: sensor name;
    options: VirtualDigitOptions (seed there is overridden by ``seed``); render_ahead:
    frames a background thread renders ahead of ``read()`` (0: render inside ``read()``),
    so a runtime reading this source measures itself, not the renderer (a render takes
    10-13 ms of the 16.7 ms frame on a 2-core host).

    Arrival stamps (``TimedFrame.arrival_ns``, monotonic ns): unpaced, when the frame's
    render finished; realtime, when it fell due (or, if the renderer was behind, when its
    render finished). Frames are the same, in the same order, with or without render-ahead.
    """

    name = "virtual-digit"

    def __init__(self, seed: int = 0, n_grasps: int = 3, fps: float = 60.0, *,
                 peak_n: tuple[float, float] = (3.0, 14.0), lead_in_s: float = 1.0,
                 indenters: list[str] | None = None, edge_fraction: float = 0.1, led_drift: float = 0.02,
                 realtime: bool = False, start_ns: int | None = None, name: str = "virtual-digit",
                 options: VirtualDigitOptions | None = None, render_ahead: int = 2) -> None:
        super().__init__()
        c = "VirtualDigitSource"
        expect(seed, int, f"{c}.seed", **bounds(SEED))
        expect(n_grasps, int, f"{c}.n_grasps", "an integer in [1, 10000] (grasps before the stream ends)",
               **bounds(GRASPS))
        expect(fps, float, f"{c}.fps", "a frame rate in [0.01, 10000] per second", **bounds(FPS))
        expect(peak_n, tuple[float, float], f"{c}.peak_n", "(low, high) peak forces in N, in [0, 1000]",
               **bounds(FORCE_N))
        if peak_n[0] > peak_n[1]:
            raise OptionsError(f"{c}.peak_n={tuple(peak_n)!r}: expected (low, high) with low <= high")
        expect(lead_in_s, float, f"{c}.lead_in_s", "seconds in [0, 3600]", **bounds(SPAN_S))
        expect(indenters, list[str] | None, f"{c}.indenters", "a list of indenter names, or None (the paper's 18)")
        if indenters is not None:
            from .indenters import INDENTERS

            unknown = [n for n in indenters if n not in INDENTERS]
            if unknown or not indenters:
                raise OptionsError(f"{c}.indenters={indenters!r}: " + (f"unknown {unknown[0]!r}; " if unknown else
                                   "empty; ") + f"expected names of {', '.join(INDENTERS)}")
        expect(edge_fraction, float, f"{c}.edge_fraction", ge=0, le=1)
        expect(led_drift, float, f"{c}.led_drift", ge=0)
        expect(realtime, bool, f"{c}.realtime")
        expect(start_ns, int | None, f"{c}.start_ns", "monotonic ns, or None (now)")
        expect(name, str, f"{c}.name", nonempty=True)
        expect(options, VirtualDigitOptions | None, f"{c}.options", "a VirtualDigitOptions or None (the defaults)")
        expect(render_ahead, int, f"{c}.render_ahead", "frames in [0, 1000] (0 renders inside read())", ge=0, le=1000)
        self.name = name
        opts = options or VirtualDigitOptions()
        from dataclasses import replace

        self.digit = VirtualDigit(replace(opts, seed=seed))
        self.fps = float(fps)
        self.realtime = realtime
        self._rng = np.random.default_rng([seed, 7])
        self._indenters = list(indenters or paper_indenter_names())
        self._plan = self._make_plan(n_grasps, peak_n, lead_in_s, edge_fraction)
        self._drift_phase = self._rng.uniform(0, 2 * np.pi, 3)
        self._led_drift = led_drift
        self._start_ns = time.monotonic_ns() if start_ns is None else int(start_ns)
        self._i = 0
        self._t0: int | None = None
        self._ahead = int(render_ahead)
        self._queue: queue.Queue[TimedFrame | None] | None = None
        self._stop: threading.Event | None = None
        self._thread: threading.Thread | None = None

    def _make_plan(self, n_grasps, peak_n, lead_in_s, edge_fraction) -> list[tuple]:
        """(force, phase, grasp, contact) per frame."""
        rng, fps = self._rng, self.fps
        plan: list[tuple] = [(0.0, "no_contact", -1, None)] * max(int(round(lead_in_s * fps)), 1)
        for g in range(n_grasps):
            contact = sample_contact(rng, str(rng.choice(self._indenters)), edge_fraction)
            peak = float(rng.uniform(*peak_n))
            n_app = int(rng.uniform(0.2, 0.4) * fps)
            n_ramp = int(rng.uniform(0.6, 1.2) * fps)
            n_hold = int(rng.uniform(0.5, 1.0) * fps)
            n_rel = int(rng.uniform(0.4, 0.8) * fps)
            n_after = int(rng.uniform(0.2, 0.4) * fps)
            plan += [(0.0, "approach", g, contact)] * n_app
            for k in range(n_ramp):
                s = (k + 1) / n_ramp
                plan.append((peak * s * s * (3 - 2 * s), "ramp", g, contact))  # smoothstep rise
            tremor = rng.normal(0.0, 0.01 * peak, n_hold)
            plan += [(max(peak + float(t), 0.0), "hold", g, contact) for t in tremor]
            for k in range(n_rel):
                s = 1.0 - (k + 1) / n_rel
                plan.append((peak * s * s * (3 - 2 * s), "release", g, contact))
            plan += [(0.0, "no_contact", g, None)] * n_after
        return plan

    def __len__(self) -> int:
        return len(self._plan)

    def _render(self, i: int) -> TimedFrame:
        """Frame i of the plan, stamped with when its render finished (arrival_ns)."""
        force, phase, grasp, contact = self._plan[i]
        t = i / self.fps
        gain = 1.0 + self._led_drift * np.sin(2 * np.pi * t / 9.0 + self._drift_phase)
        out = self.digit.render(contact if force > 0 else None, force, led_gain=gain)
        meta = dict(out.meta, phase=phase, grasp=grasp)
        if contact is not None and "indenter" not in meta:
            meta.update(indenter=str(contact.indenter), stiffness=contact.stiffness)
        ts = self._start_ns + int(round(i * 1e9 / self.fps))
        return TimedFrame(frame=out.frame, timestamp_ns=ts, index=i, truth_n=float(force), meta=meta,
                          arrival_ns=time.monotonic_ns())

    @staticmethod
    def _render_loop(ref: weakref.ReferenceType[VirtualDigitSource], first: int,
                     q: queue.Queue[TimedFrame | None], stop: threading.Event) -> None:
        """Render frames ``first``, ... into ``q``, then None (the end of the stream), until
        ``stop`` is set. Holds the source only while it renders a frame: a source dropped
        without close() sets ``stop`` (its finalizer) and the thread ends."""
        i = first
        while not stop.is_set():
            src = ref()
            if src is None:
                return
            item = src._render(i) if i < len(src._plan) else None  # rendered lazily
            del src
            while not stop.is_set():
                try:
                    q.put(item, timeout=0.1)
                    break
                except queue.Full:
                    continue
            if item is None:
                return
            i += 1

    def _next_rendered(self) -> TimedFrame | None:
        if self._queue is None:
            self._queue = queue.Queue(maxsize=self._ahead)
            self._stop = threading.Event()
            self._thread = threading.Thread(target=self._render_loop,
                                            args=(weakref.ref(self), self._i, self._queue, self._stop),
                                            name=f"render-{self.name}", daemon=True)
            weakref.finalize(self, self._stop.set)  # dropped without close(): the thread ends too
            self._thread.start()
        return self._queue.get()

    def read(self) -> TimedFrame | None:
        if self._i >= len(self._plan):
            return None
        item = self._next_rendered() if self._ahead else self._render(self._i)
        if item is None:  # pragma: no cover - the plan length guards this
            return None
        if self.realtime:
            if self._t0 is None:
                self._t0 = time.monotonic_ns()
            due = self._t0 + int(round(item.index * 1e9 / self.fps))
            now = time.monotonic_ns()
            if due > now:
                time.sleep((due - now) / 1e9)
            item.arrival_ns = max(due, item.arrival_ns or due)
        self._i += 1
        self.stats.frames += 1
        return item

    def close(self) -> None:
        """Stop the render-ahead thread (frames not yet read are dropped); safe to call twice."""
        if self._stop is not None:
            self._stop.set()
        if self._thread is not None and self._thread.is_alive():
            self._thread.join(timeout=1.0)
        self._thread = None
        self._i = len(self._plan)
