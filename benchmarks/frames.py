"""Synthetic DIGIT frames in contact (and their depth images) for latency runs and int8
calibration, rendered once by the virtual DIGIT and cached under benchmarks/cache/."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
CACHE = Path(os.environ.get("TACTILE_FORCE_CACHE", REPO / "benchmarks" / "cache"))


@dataclass
class FramePool:
    """rgb (N,320,240,3) uint8 BGR frames in contact, depth (N,320,240,1) uint8 made by the
    runtime's gate + depth stage, force (N,) N, background (K,320,240,3) no-contact frames,
    png: the rgb frames encoded as PNG bytes (what a replay source decodes)."""

    rgb: np.ndarray
    depth: np.ndarray
    force: np.ndarray
    background: np.ndarray
    png: list[bytes]

    def calibration(self, variant: str, n: int | None = None):
        """export.CalibrationData with the inputs ``variant`` needs."""
        from tactile_force.export import CalibrationData

        k = len(self.force) if n is None else min(n, len(self.force))
        inputs = {}
        if variant in ("rgbmod", "rgbmod+d"):
            inputs["rgb"] = self.rgb[:k]
        if variant != "rgbmod":
            inputs["depth"] = self.depth[:k]
        return CalibrationData(inputs, self.force[:k].astype(np.float64),
                               f"{k} virtual DIGIT frames in contact (seed 0)",
                               [str(i) for i in range(k)])


def depth_stage():
    """The runtime's depth stage with the virtual DIGIT's colour->normal calibration, as the
    reference depth models were trained with it."""
    from .reference import virtual_depth_stage

    return virtual_depth_stage()


def contact_renders(seed: int):
    """The virtual DIGIT pressed by random indenters (paper shapes + sphere, marble, cylinder;
    1.5-14.5 N), each render judged by a fresh contact gate on 5 no-contact backgrounds.

    Returns
    -------
    (backgrounds (5,320,240,3) uint8 BGR, an endless iterator of (frame HxWx3 uint8 BGR,
    force N, GateResult)); callers keep the renders they can use.
    """
    from tactile_force.edge import ContactGate
    from tactile_force.edge.synthetic import ContactSpec, VirtualDigit, VirtualDigitOptions, paper_indenter_names

    digit = VirtualDigit(VirtualDigitOptions(seed=seed))
    rng = np.random.default_rng(seed)
    names = paper_indenter_names() + ["sphere_4mm", "marble", "cylinder_8mm"]
    bgs = np.stack([digit.render(None, 0.0).frame for _ in range(5)])

    def renders():
        while True:
            spec = ContactSpec(names[int(rng.integers(len(names)))], (rng.uniform(90, 230), rng.uniform(70, 170)),
                               rotation_deg=float(rng.uniform(0, 360)))
            f = float(rng.uniform(1.5, 14.5))
            frame = digit.render(spec, f).frame
            gate = ContactGate()
            gate.capture_background(bgs)
            yield frame, f, gate.update(frame)

    return bgs, renders()


def _render(n: int, seed: int) -> FramePool:
    bgs, renders = contact_renders(seed)
    stage = depth_stage()
    rgb, depth, force = [], [], []
    for frame, f, g in renders:
        if len(rgb) >= n:
            break
        if not g.contact:
            continue
        res = stage.process(frame, g.mask)
        if not res.ok:
            continue
        rgb.append(frame)
        depth.append(res.depth)
        force.append(f)
    png = [cv2.imencode(".png", f)[1].tobytes() for f in rgb]
    return FramePool(np.stack(rgb), np.stack(depth), np.asarray(force, np.float32), bgs, png)


def frame_pool(n: int = 64, seed: int = 0) -> FramePool:
    """``n`` frames in contact (cached in benchmarks/cache/latency_frames-n{n}-seed{seed}.npz)."""
    path = CACHE / f"latency_frames-n{n}-seed{seed}.npz"
    if path.is_file():
        z = np.load(path)
        png = [cv2.imencode(".png", f)[1].tobytes() for f in z["rgb"]]
        return FramePool(z["rgb"], z["depth"], z["force"], z["background"], png)
    pool = _render(n, seed)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, rgb=pool.rgb, depth=pool.depth, force=pool.force, background=pool.background)
    os.replace(tmp, path)
    return pool
