"""Contact gate: does anything touch the gel? Background model, difference mask, hysteresis.

The gate keeps a background image of the gel without contact (mean of the first N frames, or
an explicit :meth:`ContactGate.capture_background`), compares every frame with it per pixel
(blur, drift-compensated colour difference, threshold, morphology, hole filling) and
decides contact from the masked area with hysteresis: contact turns on when the area
reaches ``on_area_frac`` of the frame and off only when it falls below ``off_area_frac``.
While there is no contact the background follows slow LED drift (``refresh_rate``).

The work runs on a frame downscaled by ``downscale`` (default 2: same masks, ~3x faster,
see docs/runtime.md); the mask is returned at full resolution, because the depth stage
filters its full-size depth image with it. Any frame size works (DIGIT 320x240, GelSight
Mini 480x640); the first background fixes the size.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import cv2
import numpy as np

from .errors import FrameError
from .frames import TimedFrame, check_frame


@dataclass
class GateOptions:
    """Gate settings. Areas are fractions of the frame area so one setting fits any size.

    background_frames: frames averaged into the background when it is learnt at start.
    blur: odd Gaussian kernel size in pixels at the working (downscaled) resolution.
    threshold: colour difference (0..255, max over B, G, R after removing the global
        per-channel drift) above which a pixel counts as changed.
    on_area_frac / off_area_frac: hysteresis thresholds on the masked area.
    min_blob_frac: connected regions smaller than this are dropped (noise specks).
    downscale: integer factor the frame is shrunk by before the work (1 = full res).
    refresh_rate: per-frame weight of a no-contact frame in the background (0 = frozen).
    saturation_threshold / saturation_area_frac: a changed area (difference above
        saturation_threshold) covering this fraction of the frame reads as gel saturation.
    convex_hull: replace each kept blob by its convex hull (the contact patch of a convex
        indenter is convex). Off by default: a DIGIT grasps any shape, and on the AUROVA
        frames the hull adds 30-90 % area. See :meth:`gelsight_mini`.
    """

    background_frames: int = 5
    blur: int = 5
    threshold: float = 14.0
    on_area_frac: float = 0.006
    off_area_frac: float = 0.003
    min_blob_frac: float = 0.0015
    downscale: int = 2
    refresh_rate: float = 0.02
    saturation_threshold: float = 60.0
    saturation_area_frac: float = 0.25
    convex_hull: bool = False

    @classmethod
    def gelsight_mini(cls, **overrides: object) -> "GateOptions":
        """Settings for a GelSight Mini (480x640): its LEDs make a stronger colour halo
        around the contact than a DIGIT's, so a higher threshold, and convex hulls (ball and
        other convex indenters). On the 16 labelled ball presses (shared data): IoU with the
        contact circles mean 0.65, min 0.58 (threshold 25 without hulls: 0.61, 0.54)."""
        return cls(**{"threshold": 28.0, "convex_hull": True, **overrides})

    def validate(self) -> None:
        """Raise ValueError naming the first bad field."""
        if self.background_frames < 1:
            raise ValueError(f"gate.background_frames={self.background_frames}: expected an integer >= 1")
        if self.blur < 1 or self.blur % 2 == 0:
            raise ValueError(f"gate.blur={self.blur}: expected an odd integer >= 1 (Gaussian kernel, pixels)")
        if not 0 < self.threshold < 255:
            raise ValueError(f"gate.threshold={self.threshold}: expected 0 < threshold < 255")
        if not 0 <= self.off_area_frac <= self.on_area_frac < 1:
            raise ValueError(
                f"gate.on_area_frac={self.on_area_frac}, off_area_frac={self.off_area_frac}: "
                "expected 0 <= off_area_frac <= on_area_frac < 1"
            )
        if int(self.downscale) != self.downscale or self.downscale < 1:
            raise ValueError(f"gate.downscale={self.downscale}: expected an integer >= 1")
        if not 0 <= self.refresh_rate < 1:
            raise ValueError(f"gate.refresh_rate={self.refresh_rate}: expected 0 <= rate < 1")
        if not isinstance(self.convex_hull, bool):
            raise ValueError(f"gate.convex_hull={self.convex_hull!r}: expected true or false")


class GateResult:
    """One gate decision.

    contact: gate open (after hysteresis). area_px: masked area in full-resolution pixels.
    saturation_seen: a large strongly changed area. background_ready: False while the
    background is still being learnt (then contact is False).

    mask (HxW uint8 0/255 at the frame's full resolution), centroid ((x, y) pixels or None)
    and bbox ((x, y, w, h) pixels or None) are computed on first access from the gate's
    working mask, so the hot path of an RGBmod scene, which reads neither, skips the
    upscale and the moments. The mask is a buffer the gate reuses: read or copy it before
    the next ``update``.
    """

    __slots__ = ("contact", "area_px", "saturation_seen", "background_ready", "_small", "_k", "_exact",
                 "_full", "_mask_ready", "_geometry")

    def __init__(self, contact: bool, area_px: int, saturation_seen: bool, small: np.ndarray, full: np.ndarray,
                 k: int, exact: bool, background_ready: bool = True) -> None:
        self.contact = contact
        self.area_px = area_px
        self.saturation_seen = saturation_seen
        self.background_ready = background_ready
        self._small, self._full, self._k, self._exact = small, full, k, exact
        self._mask_ready = small is full
        self._geometry: tuple | None = None

    @property
    def mask(self) -> np.ndarray:
        if not self._mask_ready:
            cv2.resize(self._small, (self._full.shape[1], self._full.shape[0]), dst=self._full,
                       interpolation=cv2.INTER_NEAREST)
            self._mask_ready = True
        return self._full

    def _measure(self) -> tuple:
        if self._geometry is None:
            if not self.area_px:
                self._geometry = (None, None)
            else:
                # From the small mask when the factor divides the frame (the nearest-neighbour
                # upscale maps every small pixel to a k x k block: exact), else the full mask.
                src, k = (self._small, self._k) if self._exact else (self.mask, 1)
                m = cv2.moments(src, binaryImage=True)
                off = (k - 1) / 2.0
                x, y, w, h = cv2.boundingRect(src)
                self._geometry = ((k * m["m10"] / m["m00"] + off, k * m["m01"] / m["m00"] + off),
                                  (int(x * k), int(y * k), int(w * k), int(h * k)))
        return self._geometry

    @property
    def centroid(self) -> tuple[float, float] | None:
        return self._measure()[0]

    @property
    def bbox(self) -> tuple[int, int, int, int] | None:
        return self._measure()[1]

    def __repr__(self) -> str:
        return (f"GateResult(contact={self.contact}, area_px={self.area_px}, saturation_seen={self.saturation_seen}, "
                f"background_ready={self.background_ready})")


class ContactGate:
    """Per-sensor contact gate; one instance per sensor, not thread-safe."""

    def __init__(self, options: GateOptions | None = None) -> None:
        self.options = options or GateOptions()
        self.options.validate()
        self._bg: np.ndarray | None = None  # blurred background, float32, working res
        self._learn: list[np.ndarray] = []
        self._shape: tuple[int, int, int] | None = None
        self._contact = False
        self._alloc_done = False

    # -- background ---------------------------------------------------------------------
    @property
    def background_ready(self) -> bool:
        return self._bg is not None

    @property
    def frame_shape(self) -> tuple[int, int, int] | None:
        """H x W x 3 the gate works at, fixed by the first background."""
        return self._shape

    def capture_background(self, frames: Iterable[np.ndarray | TimedFrame]) -> None:
        """Set the background to the mean of ``frames`` (HxWx3 uint8 BGR, no contact)."""
        work = [self._prepare(self._as_array(f, i)).copy() for i, f in enumerate(frames)]
        if not work:
            raise FrameError("capture_background: no frames given; expected at least one no-contact frame")
        self._bg = np.mean(work, axis=0, dtype=np.float32)
        self._learn.clear()
        self._contact = False

    def reset(self) -> None:
        """Forget the background; the next ``background_frames`` frames are learnt again."""
        self._bg = None
        self._learn.clear()
        self._contact = False

    # -- per frame ----------------------------------------------------------------------
    def update(self, frame: np.ndarray | TimedFrame) -> GateResult:
        """Gate one frame (HxWx3 uint8 BGR, same size as the background)."""
        arr = self._as_array(frame, None)
        work = self._prepare(arr)
        o = self.options
        if self._bg is None:
            self._learn.append(work.copy())
            if len(self._learn) >= o.background_frames:
                self._bg = np.mean(self._learn, axis=0, dtype=np.float32)
                self._learn.clear()
            self._full_mask[:] = 0
            return GateResult(False, 0, False, self._full_mask, self._full_mask, 1, True, background_ready=False)

        # Signed difference minus the global per-channel shift (LED drift, exposure), thresholded
        # on the max over B, G, R: |d - shift| > t on some channel <=> d outside [shift - t,
        # shift + t] on some channel, so one inRange + invert does subtract, abs, max and compare.
        cv2.subtract(work, self._bg, dst=self._diff, dtype=cv2.CV_32F)
        shift = cv2.mean(self._diff)
        self._lo[:] = shift[:3]
        self._hi[:] = shift[:3]
        self._lo -= o.threshold
        self._hi += o.threshold
        cv2.inRange(self._diff, self._lo, self._hi, dst=self._mask)
        cv2.bitwise_not(self._mask, dst=self._mask)
        self._lo += o.threshold - o.saturation_threshold
        self._hi -= o.threshold - o.saturation_threshold
        cv2.inRange(self._diff, self._lo, self._hi, dst=self._strong)
        strong = self._work_area - cv2.countNonZero(self._strong)
        saturation_seen = strong >= o.saturation_area_frac * self._work_area
        cv2.morphologyEx(self._mask, cv2.MORPH_OPEN, self._kernel, dst=self._mask)
        cv2.morphologyEx(self._mask, cv2.MORPH_CLOSE, self._kernel_close, dst=self._mask)

        # Keep blobs big enough to be contact, filled (a ball's flat top looks like background).
        contours, _ = cv2.findContours(self._mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        self._mask[:] = 0
        keep = [c for c in contours if cv2.contourArea(c) >= self._min_blob]
        if o.convex_hull:
            keep = [cv2.convexHull(c) for c in keep]
        if keep:
            cv2.drawContours(self._mask, keep, -1, 255, thickness=cv2.FILLED)

        s = int(o.downscale)
        small = self._mask if (s > 1 and self._exact) else self._full_mask
        if small is self._full_mask and s > 1:
            cv2.resize(self._mask, (arr.shape[1], arr.shape[0]), dst=self._full_mask, interpolation=cv2.INTER_NEAREST)
        k = s if small is self._mask else 1
        area = cv2.countNonZero(small) * k * k

        frac = area / self._full_area
        if self._contact:
            self._contact = frac >= o.off_area_frac
        else:
            self._contact = frac >= o.on_area_frac

        if not self._contact and o.refresh_rate > 0:
            cv2.accumulateWeighted(work, self._bg, o.refresh_rate)
        full = self._mask if s == 1 else self._full_mask
        return GateResult(self._contact, int(area), bool(saturation_seen), small if s > 1 else full, full, k,
                          self._exact)

    # -- internals ----------------------------------------------------------------------
    def _as_array(self, frame: np.ndarray | TimedFrame, i: int | None) -> np.ndarray:
        arr = frame.frame if isinstance(frame, TimedFrame) else frame
        name = "gate frame" if i is None else f"background frame {i}"
        arr = check_frame(arr, name=name, shape=None)
        if self._shape is None:
            self._allocate(arr.shape)
        elif arr.shape != self._shape:
            raise FrameError(f"{name}: shape {arr.shape}; this gate's background is {self._shape} "
                             "(call reset() or use one gate per sensor)")
        return arr

    def _allocate(self, shape: tuple[int, int, int]) -> None:
        o = self.options
        h, w = shape[:2]
        s = int(o.downscale)
        wh, ww = max(1, h // s), max(1, w // s)
        self._shape = tuple(shape)
        self._small = np.empty((wh, ww, 3), np.uint8)
        self._work = np.empty((wh, ww, 3), np.uint8)
        self._diff = np.empty((wh, ww, 3), np.float32)
        self._lo = np.empty(3, np.float64)
        self._hi = np.empty(3, np.float64)
        self._exact = s == 1 or (h % s == 0 and w % s == 0)
        self._mask = np.empty((wh, ww), np.uint8)
        self._strong = np.empty((wh, ww), np.uint8)
        self._full_mask = self._mask if s == 1 else np.zeros((h, w), np.uint8)
        self._work_area = wh * ww
        self._full_area = h * w
        self._min_blob = o.min_blob_frac * self._work_area
        k = max(3, (min(wh, ww) // 60) | 1)  # ~3 px at 120x160, scales with size
        self._kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))
        self._kernel_close = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * k + 1, 2 * k + 1))

    def _prepare(self, arr: np.ndarray) -> np.ndarray:
        """Downscale (INTER_AREA) + blur into the uint8 working buffer (reused; uint8 keeps
        OpenCV on its fixed-point fast paths)."""
        s = int(self.options.downscale)
        src = arr
        if s > 1:
            cv2.resize(arr, (self._small.shape[1], self._small.shape[0]), dst=self._small, interpolation=cv2.INTER_AREA)
            src = self._small
        b = self.options.blur
        if b > 1:
            cv2.GaussianBlur(src, (b, b), 0, dst=self._work)
        else:
            np.copyto(self._work, src)
        return self._work
