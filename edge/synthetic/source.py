"""VirtualDigitSource: a FrameSource of simulated grasps at 60 fps with force ground truth.

Each grasp: approach (no contact) -> ramp (smooth rise to the peak force) -> hold (peak with
a small tremor) -> release -> no contact. The stream starts with a longer no-contact lead-in
so a contact gate can learn its background, and the LEDs drift slowly over time.
"""

from __future__ import annotations

import time

import numpy as np

from ..frames import FrameSource, TimedFrame
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
    options: VirtualDigitOptions (seed there is overridden by ``seed``).
    """

    name = "virtual-digit"

    def __init__(self, seed: int = 0, n_grasps: int = 3, fps: float = 60.0, *,
                 peak_n: tuple[float, float] = (3.0, 14.0), lead_in_s: float = 1.0,
                 indenters: list[str] | None = None, edge_fraction: float = 0.1, led_drift: float = 0.02,
                 realtime: bool = False, start_ns: int | None = None, name: str = "virtual-digit",
                 options: VirtualDigitOptions | None = None) -> None:
        super().__init__()
        self.name = name
        if n_grasps < 1 or not (fps > 0):
            raise ValueError(f"n_grasps={n_grasps}, fps={fps}: expected n_grasps >= 1 and fps > 0")
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
        self._t0 = None

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

    def read(self) -> TimedFrame | None:
        if self._i >= len(self._plan):
            return None
        i = self._i
        force, phase, grasp, contact = self._plan[i]
        t = i / self.fps
        gain = 1.0 + self._led_drift * np.sin(2 * np.pi * t / 9.0 + self._drift_phase)
        out = self.digit.render(contact if force > 0 else None, force, led_gain=gain)
        meta = dict(out.meta, phase=phase, grasp=grasp)
        if contact is not None and "indenter" not in meta:
            meta.update(indenter=str(contact.indenter), stiffness=contact.stiffness)
        ts = self._start_ns + int(round(i * 1e9 / self.fps))
        if self.realtime:
            if self._t0 is None:
                self._t0 = time.monotonic()
            delay = self._t0 + t - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        self._i += 1
        self.stats.frames += 1
        return TimedFrame(frame=out.frame, timestamp_ns=ts, index=i, truth_n=float(force), meta=meta)
