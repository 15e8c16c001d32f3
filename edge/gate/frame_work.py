"""The contact gate's per-frame image work, into buffers allocated once per frame size.

:class:`FrameWork` does, for :class:`~tactile_force.edge.gate.contact_gate.ContactGate`, what every
frame needs before the judging: the one downscale (edge/gate/reduce.py's box average), the 3 x 3 blur
of the reduced image (``work``), its thumbnail, the pixel-noise level and the changed-pixel mask with
|frame - model| (one kernel call for the first four), and for the judging the thumbnail's photometric
fit (:meth:`FrameWork.fit`: one kernel call for its residual and sums over the cells that fit; every
cell, after a sudden change, keeps OpenCV's means) and check (:meth:`FrameWork.residual`) and the
contact blob's area and deformation (:meth:`FrameWork.contact_stats`).

Two equal paths: OpenCV calls (the robot-side install), and where the ``fast`` extra's kernels are
compiled for this environment (edge/compiled_path.py: loaded from numba's cache when the gate is
made, never compiled there) the kernels of edge/gate/kernels.py for the common case (a power-of-two
factor dividing the frame, blur 3). They equal the OpenCV calls bit for bit
(tests/edge/gate/test_kernels.py), so a reading is the same on either path. A factor that is not a
power of two, one that does not divide the frame, another blur or a working image under 2 x 2 pixels
always takes the OpenCV calls.
"""

from __future__ import annotations

import math
from types import ModuleType

import cv2
import numpy as np

from .. import compiled_path
from ..bundle.manifest import Reduction
from .reduce import FrameReducer, default_reduction

__all__ = ["FrameWork"]

#: Rows the compiled blur and noise kernels work on at once: long loops over a scratch of this many rows,
#: not of the whole image.
BLUR_BAND = 8

#: Thumbnail cell size in full-resolution pixels (a 320x240 frame -> 20x15 cells).
THUMB_CELL_PX = 16


def _gaussian(src: np.ndarray, dst: np.ndarray, b: int) -> None:
    """``dst`` = ``src`` blurred by an odd ``b`` x ``b`` Gaussian (``b`` = 1: a copy)."""
    if b > 1:
        cv2.GaussianBlur(src, (b, b), 0, dst=dst)
    else:
        np.copyto(dst, src)


class FrameWork:
    """Reduce, blur, thumbnail, noise level and changed mask of H x W x 3 uint8 frames.

    Parameters
    ----------
    shape
        (H, W, 3) of the frames.
    downscale
        Integer factor k of the working resolution (H/k x W/k; 1 = full resolution).
    blur
        Odd Gaussian kernel size at the working resolution (1 = none).
    threshold
        Colour difference (grey levels) above which a channel marks a pixel changed.

    Buffers (reused every frame): ``small`` (the reduced image), ``work`` (its blur), ``thumb``,
    ``ad`` (|work - model|) and ``mask`` (changed 255 / 0), all of the working size but the thumbnail.
    """

    def __init__(self, shape: tuple[int, int, int], downscale: int, blur: int, threshold: float) -> None:
        h, w = int(shape[0]), int(shape[1])
        s = int(downscale)
        wh, ww = max(1, h // s), max(1, w // s)
        self.shape = (h, w, int(shape[2]))
        self.downscale, self.blur, self.threshold = s, int(blur), float(threshold)
        self.exact = s == 1 or (h % s == 0 and w % s == 0)
        self.small = np.empty((wh, ww, 3), np.uint8)
        self.work = np.empty((wh, ww, 3), np.uint8)
        self.thumb = np.empty((max(2, h // THUMB_CELL_PX), max(2, w // THUMB_CELL_PX), 3), np.uint8)
        self.ad = np.empty((wh, ww, 3), np.uint8)
        self.mask = np.empty((wh, ww), np.uint8)
        # the changed mask's bound: inRange's upper bound on uint8 is the threshold rounded half
        # to even (saturate_cast), so "changed" is a channel of |work - model| above this integer
        self.ub = min(255, round(float(threshold)))
        self._ad2 = self.ad.reshape(wh, ww * 3)
        self._work2 = self.work.reshape(wh, ww * 3)
        self._small2 = self.small.reshape(wh, ww * 3)
        # The one downscale: an exact box average (edge/gate/reduce.py) when the factor divides
        # the frame, else INTER_LINEAR at x2 / one pixel per block above.
        self.reducer = FrameReducer(default_reduction(s), self.shape) if self.exact and s > 1 else None
        steps = self.reducer is not None and self.reducer.reduction.method is Reduction.AREA_2X_STEPS
        blur3 = self.blur == 3 and wh >= 2 and ww >= 2
        #: the compiled kernels where this process has them (edge/compiled_path.py), else None: the OpenCV path
        self._k: ModuleType | None = compiled_path.gate_kernels()
        self._t = np.empty(BLUR_BAND * ww * 3, np.uint16)  # the blur's vertical sums, a band of rows at a time
        self._band = np.empty(BLUR_BAND * ww * 3, np.uint8)  # a band of the noise kernel's blurred rows
        self._v = np.empty((s, w * 3), np.uint8) if steps else None
        self._blur3 = blur3
        self._none = np.empty((0, ww * 3), np.uint8)  # "no blur" for the reduction kernel
        # Pixel noise is judged on one pixel per k x k block of the full frame above x2 (a box
        # average hides pixel noise): the subsample and its blur.
        self.sub = np.empty((wh, ww, 3), np.uint8) if self.reducer is not None and s > 2 else None
        self._noise_kernel = self.sub is not None and blur3
        self._sub_blur = np.empty((wh, ww, 3), np.uint8)
        self._noise_d = np.empty((wh, ww, 3), np.uint8)
        self._sums = np.zeros(3, np.int64)
        self._sub2 = self.sub.reshape(wh, ww * 3) if self.sub is not None else self._none
        self._noise_of: np.ndarray | None = None  # the frame whose noise level the last reduce measured
        self._noise_level = 0.0
        self._inv_n = 1.0 / (wh * ww)
        self._gt = np.empty(ww * 3, np.float64)  # the changed kernel's gain / offset per value of a row
        self._ot = np.empty(ww * 3, np.float64)
        # The thumbnail by the kernel where it is ``work`` shrunk by an even integer factor f
        # (INTER_LINEAR there is the mean of the 2 x 2 pixels around each cell's centre).
        th, tw = self.thumb.shape[:2]
        f = wh // th
        self._f = f if f % 2 == 0 and th * f == wh and tw * f == ww else 0
        self._thumb2 = self.thumb.reshape(th, tw * 3)
        self._no_thumb = np.empty((0, tw * 3), np.uint8)
        self._thumb_made = False  # the last reduce made the thumbnail of ``work``
        self._fit_sums = np.zeros(13, np.float64)  # the fit's sums (kernels.fit_sums)
        self._moments: list[tuple[float, float, float, float]] = []
        # the OpenCV path's buffers: the model image, its uint8 form, the thumbnail's |difference|
        self._model_img = np.empty((wh, ww, 3), np.float32)
        self._model_u8 = np.empty((wh, ww, 3), np.uint8)
        self._tdiff = np.empty(self.thumb.shape, np.float32)
        self._tprod = np.empty(self.thumb.shape, np.float32)
        self._zero3 = np.zeros(3)
        self._thr3 = np.full(3, float(threshold))
        self._tol3 = np.zeros(3)

    def reduce(self, frame: np.ndarray, blur: bool = False, noise: bool = False) -> None:
        """The frame's one downscale into ``small``; with ``blur`` also its blur into ``work``, with
        ``noise`` also its pixel-noise level for the next :meth:`noise` of this frame (one kernel
        call where the kernels apply)."""
        s = self.downscale
        self._noise_of = None
        self._thumb_made = False
        k = self._k
        if k is not None and self._v is not None:
            h, w = self.shape[:2]
            noise = noise and self._noise_kernel
            blur3 = blur and self._blur3
            self._thumb_made = blur3 and self._f > 0
            k.reduce_blur(frame.reshape(h, w * 3), s, self._small2, self._work2 if blur3 else self._none,
                          self._sub2 if noise else self._none, self._v, self._t, self._band, self._sums, self._f,
                          self._thumb2 if self._thumb_made else self._no_thumb)
            if noise:
                self._noise_of, self._noise_level = frame, self._level()
            if blur and not self._blur3:
                self._blur_cv()
            return
        self.reduce_without_kernels(frame)
        if blur:
            self.blur_small()

    def reduce_without_kernels(self, frame: np.ndarray) -> None:
        """``small`` by OpenCV: the exact box average (edge/gate/reduce.py) when the factor divides
        the frame, else INTER_LINEAR at x2 and one pixel per block above."""
        s = self.downscale
        if self.reducer is not None:
            self.reducer(frame, out=self.small)
        elif s > 1:
            cv2.resize(frame, (self.small.shape[1], self.small.shape[0]), dst=self.small,
                       interpolation=cv2.INTER_LINEAR if s <= 2 else cv2.INTER_NEAREST)
        else:
            np.copyto(self.small, frame)

    def blur_small(self) -> None:
        """``work`` = the blur of ``small``."""
        self._thumb_made = False
        if self._blur3 and self._k is not None:
            self._k.blur3(self._small2, self._t, self._work2)
        else:
            self._blur_cv()

    def _blur_cv(self) -> None:
        _gaussian(self.small, self.work, self.blur)

    def thumbnail(self) -> np.ndarray:
        """``thumb`` = ``work`` shrunk to the thumbnail (INTER_LINEAR; made by the reduction's kernel
        call where the factor allows)."""
        t = self.thumb
        if self._thumb_made:
            return t
        cv2.resize(self.work, (t.shape[1], t.shape[0]), dst=t, interpolation=cv2.INTER_LINEAR)
        return t

    def noise(self, frame: np.ndarray) -> float:
        """Pixel-noise level of ``frame`` (the frame ``work`` was made from): the largest
        per-channel mean |subsample - its blur| above x2 (see ``sub``), else of |small - work|
        (grey levels)."""
        if self._noise_of is frame:  # measured by the reduce of this frame: taken once
            self._noise_of = None
            return self._noise_level
        if self._noise_kernel and self._k is not None:
            h, w = self.shape[:2]
            self._k.noise_sums(frame.reshape(h, w * 3), self.downscale, self._sub2, self._t, self._band, self._sums)
            return self._level()
        if self.sub is None:
            cv2.absdiff(self.small, self.work, dst=self._noise_d)
        else:
            cv2.resize(frame, (self.sub.shape[1], self.sub.shape[0]), dst=self.sub, interpolation=cv2.INTER_NEAREST)
            _gaussian(self.sub, self._sub_blur, self.blur)
            cv2.absdiff(self.sub, self._sub_blur, dst=self._noise_d)
        return float(max(cv2.mean(self._noise_d)[:3]))

    def _level(self, inv: float | None = None) -> float:
        """The largest per-channel mean from a kernel's integer sums in ``_sums``, as ``cv2.mean``
        makes it: the sum times ``inv`` = 1 / count (default: the working image's pixels, the noise
        level)."""
        inv = self._inv_n if inv is None else inv
        s0, s1, s2 = self._sums.tolist()
        return max(s0 * inv, s1 * inv, s2 * inv)

    def residual(self, bg_thumb: np.ndarray, thumb: np.ndarray, model: np.ndarray, tmodel: np.ndarray,
                 inl: np.ndarray, tol: np.float32) -> int:
        """The thumbnail's fit: ``tmodel`` = gain x ``bg_thumb`` + offset (``model`` as in :meth:`changed`),
        ``inl`` 255 where |``thumb`` - ``tmodel``| <= ``tol`` on every channel, else 0; returns the count
        of 255 cells. Thumbnails: rows x cols x 3 float32; ``inl`` rows x cols uint8."""
        if self._k is not None:
            return int(self._k.residual(bg_thumb, model, thumb, tmodel, inl, tol))
        cv2.transform(bg_thumb, model, dst=tmodel)
        diff = cv2.absdiff(thumb, tmodel, dst=self._tdiff)  # a new array where the shapes differ
        self._tol3.fill(float(tol))
        cv2.inRange(diff, self._zero3, self._tol3, dst=inl)
        return cv2.countNonZero(inl)

    def fit(self, bg_thumb: np.ndarray, thumb: np.ndarray, y: np.ndarray, model: np.ndarray, tmodel: np.ndarray,
            inl: np.ndarray, tol: np.float32) -> None:
        """The photometric model fitted: per channel the gain and offset of ``y`` = gain x ``bg_thumb`` +
        offset, least squares over the cells that fit the current ``model`` (:meth:`residual`; every
        cell when fewer than half do: after a sudden change), written into ``model`` (the 3 x 4 float32
        matrix: gain on the diagonal, offset in the last column). ``y`` = ``thumb`` (rows x cols x 3
        uint8) as float32; ``tmodel`` and ``inl`` are left as :meth:`residual` made them for the
        current model. The means and deviations as ``cv2.meanStdDev`` / ``cv2.mean`` make them (sums in
        float64 cell by cell, times 1 / count), the gain from them as the gate always made it."""
        if self._k is not None:
            fits = self._k.fit_sums(bg_thumb, thumb, y, model, tmodel, inl, tol, self._fit_sums) >= inl.size // 2
        else:
            np.copyto(y, thumb, casting="unsafe")
            fits = self.residual(bg_thumb, y, model, tmodel, inl, tol) >= inl.size // 2
        if fits and self._k is not None:
            self._moments = self._masked_moments()
        else:  # OpenCV's own means (the kernel's masked sums equal them; its unmasked mean adds in another order)
            mask = inl if fits else None
            mx, sx = cv2.meanStdDev(bg_thumb, mask=mask)
            prod = cv2.multiply(bg_thumb, y, dst=self._tprod)  # a new array where the shapes differ
            means_y, means_xy = cv2.mean(y, mask=mask), cv2.mean(prod, mask=mask)
            self._moments = [(float(mx[c, 0]), float(sx[c, 0]), means_y[c], means_xy[c]) for c in range(3)]
        for c, (m, sd, my, mxy) in enumerate(self._moments):
            var = sd ** 2  # pow, not sd * sd: they differ in the last bit now and then
            g = (mxy - m * my) / var if var > 1e-3 else 0.0
            model[c, c] = g
            model[c, 3] = my - g * m

    def fit_moments(self) -> list[tuple[float, float, float, float]]:
        """Per channel B, G, R the last :meth:`fit`'s (mean, standard deviation) of the background
        thumbnail, mean of the frame's and mean of their float32 product over the cells it used
        (grey levels): what ``cv2.meanStdDev`` and ``cv2.mean`` give, to the bit."""
        return self._moments

    def _masked_moments(self) -> list[tuple[float, float, float, float]]:
        """The moments from the kernel's sums over the cells that fit (float64 cell by cell, times
        1 / count; the deviation the square root of mean square - mean squared, as OpenCV)."""
        s = self._fit_sums.tolist()
        scale = 1.0 / s[12]
        out = []
        for c in range(3):
            m = s[c] * scale
            out.append((m, math.sqrt(max(s[3 + c] * scale - m * m, 0.0)), s[6 + c] * scale, s[9 + c] * scale))
        return out

    def contact_stats(self) -> tuple[int, float]:
        """(area: the nonzero pixels of ``mask``, deformation: the largest per-channel mean of ``ad``
        over them, grey levels; 0.0 for an empty mask), as ``cv2.countNonZero`` and ``cv2.mean``
        with the mask give them."""
        if self._k is None:
            n = cv2.countNonZero(self.mask)
            return (n, float(max(cv2.mean(self.ad, mask=self.mask)[:3]))) if n else (0, 0.0)
        n = int(self._k.masked_sums(self.mask, self.ad, self._sums))
        return (n, self._level(1.0 / n)) if n else (0, 0.0)

    def changed(self, bg: np.ndarray, model: np.ndarray) -> int:
        """|work - u8(gain x bg + offset)| per channel into ``ad`` and the changed mask (255 where a
        channel of it exceeds the threshold) into ``mask``; returns the changed pixel count.

        bg: h x w x 3 float32 (the background); model: the 3 x 4 float32 photometric matrix
        (diagonal gain, offset in the last column; what ``cv2.transform`` would apply)."""
        if self._k is not None:
            return int(self._k.changed(bg.reshape(self._ad2.shape), model, self._work2, self._ad2, self.mask,
                                       self.ub, self._gt, self._ot))
        cv2.transform(bg, model, dst=self._model_img)
        cv2.convertScaleAbs(self._model_img, dst=self._model_u8)
        cv2.absdiff(self.work, self._model_u8, dst=self.ad)
        cv2.inRange(self.ad, self._zero3, self._thr3, dst=self.mask)
        cv2.bitwise_not(self.mask, dst=self.mask)
        return cv2.countNonZero(self.mask)
