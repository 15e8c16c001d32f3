"""Virtual DIGIT frames in contact, rendered in memory (no torch), and the virtual DIGIT's depth
stage: what the latency measurement, the bench and int8 calibration read.

- :func:`contact_renders`: the virtual DIGIT pressed by random indenters, each render judged;
- :func:`frame_pool`: frames in contact with their depth images (cached under the cache dir);
- :func:`contact_frames`: frames in contact without depth (the runtime's own depth stage makes
  it), rendered on every call: what ``tactile-force bench`` measures on;
- :func:`virtual_depth_stage` / :func:`virtual_depth_record`: the runtime's depth stage with
  the virtual DIGIT's calibration (package:virtual_digit_depth.npz), as the reference depth
  models were trained with it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import cv2
import numpy as np
from tactile_force.edge.scene import PACKAGE_DIR

from .paths import cache_dir

#: The depth stage's mapping for the virtual DIGIT (benchmarks/virtual_depth_calibration.py).
VIRTUAL_DEPTH_MAPPING = PACKAGE_DIR / "assets" / "virtual_digit_depth.npz"
#: 8-bit levels per pixel of reconstructed indentation for the virtual DIGIT. Its
#: reconstructed heights reach ~46 px at 15 N (p99 43 px), so 255 levels span 48 px; the
#: depth stage's default (255/20) would clip 69 % of the training frames at 255.
VIRTUAL_DEPTH_LEVELS_PER_PX = 255.0 / 48.0


@dataclass
class FramePool:
    """rgb (N,320,240,3) uint8 BGR frames in contact, depth (N,320,240,1) uint8 made by the
    runtime's gate + depth stage (zeros where not made), force (N,) N, background
    (K,320,240,3) no-contact frames, png: the rgb frames encoded as PNG bytes (what a replay
    source decodes; empty where not needed)."""

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


def network_reduction(k: int):
    """How a frame is reduced to a network input 1/k of the frame: the package's default for
    the factor (edge/gate/reduce.py), recorded in a manifest's inputs and depth record."""
    from tactile_force.edge.gate.reduce import default_reduction

    return default_reduction(k)


def virtual_depth_record(downscale: int = 1):
    """The manifest's depth record of the reference depth models (what the runtime rebuilds)."""
    from tactile_force.edge.bundle.manifest import DepthRecord
    from tactile_force.edge.bundle.store import sha256_file

    return DepthRecord(mapping=f"package:{VIRTUAL_DEPTH_MAPPING.name}", mode="exact",
                       levels_per_px=VIRTUAL_DEPTH_LEVELS_PER_PX, mapping_sha256=sha256_file(VIRTUAL_DEPTH_MAPPING),
                       mask="contact gate (GateOptions defaults)", reduction=network_reduction(downscale))


def virtual_depth_stage(downscale: int = 1):
    """The runtime's depth stage as the reference depth models were trained with it
    (``downscale`` k: at the network resolution 320/k x 240/k)."""
    from tactile_force.edge.depth import DepthOptions, DepthStage

    rec = virtual_depth_record(downscale)
    return DepthStage(DepthOptions(mapping=VIRTUAL_DEPTH_MAPPING, mode=rec.mode,
                                   levels_per_px=VIRTUAL_DEPTH_LEVELS_PER_PX, downscale=rec.downscale,
                                   reduction=rec.reduction.method.value))


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
    stage = virtual_depth_stage()
    rgb: list[np.ndarray] = []
    depth: list[np.ndarray] = []
    force: list[float] = []
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
    """``n`` frames in contact with their depth images (virtual DIGIT calibration), cached in
    the cache dir as latency_frames-n{n}-seed{seed}.npz."""
    path = cache_dir() / f"latency_frames-n{n}-seed{seed}.npz"
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


def contact_frames(n: int = 64, seed: int = 0) -> FramePool:
    """``n`` virtual DIGIT frames in contact and 5 no-contact backgrounds, rendered in memory
    (no torch, no cache); depth left empty: the runtime's own depth stage makes it.

    Parameters
    ----------
    n : int
        Frames in contact (the contact gate opens on each, judging nothing wrong).
    seed : int
        Seed of the virtual DIGIT and of the contacts.
    """
    from tactile_force.edge.report.logs import quiet_loggers

    rgb: list[np.ndarray] = []
    force: list[float] = []
    # renders the gate cannot judge are dropped here, not warned about
    with quiet_loggers("tactile_force.edge.gate.contact_gate"):
        bgs, renders = contact_renders(seed)
        for frame, f, g in renders:
            if len(rgb) >= n:
                break
            if g.contact and not g.mismatch and not g.invalid:
                rgb.append(frame)
                force.append(f)
    arr = np.stack(rgb)
    return FramePool(arr, np.zeros((*arr.shape[:3], 1), np.uint8), np.asarray(force, np.float32), bgs, [])
