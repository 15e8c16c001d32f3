"""The OpenCV calls the gate's compiled kernels replace (edge/gate/kernels.py): the oracle they are
compared against, bit for bit (tests/edge/gate/test_kernels.py). Not a runtime path."""

from __future__ import annotations

import cv2
import numpy as np
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.gate.frame_work import FrameWork
from tactile_force.edge.gate.reduce import FrameReducer, default_reduction


def reduce_cv(frame: np.ndarray, k: int) -> np.ndarray:
    """``area-2x-steps`` by ``k`` (a power of two): OpenCV INTER_AREA at 1/2, log2(k) times."""
    return FrameReducer(default_reduction(k), frame.shape).__call__(frame).copy()


def blur_cv(img: np.ndarray) -> np.ndarray:
    """cv2.GaussianBlur(img, (3, 3), 0)."""
    return cv2.GaussianBlur(img, (3, 3), 0)


def noise_cv(frame: np.ndarray, k: int) -> float:
    """Largest per-channel mean |nearest subsample - its 3 x 3 blur| (cv2.mean)."""
    h, w = frame.shape[0] // k, frame.shape[1] // k
    sub = cv2.resize(frame, (w, h), interpolation=cv2.INTER_NEAREST)
    return float(max(cv2.mean(cv2.absdiff(sub, blur_cv(sub)))[:3]))


def changed_cv(work: np.ndarray, bg: np.ndarray, model: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """(|work - convertScaleAbs(transform(bg, model))|, the mask 255 where a channel exceeds threshold)."""
    m = cv2.convertScaleAbs(cv2.transform(bg, model))
    ad = cv2.absdiff(work, m)
    mask = cv2.bitwise_not(cv2.inRange(ad, np.zeros(3), np.full(3, float(threshold))))
    return ad, mask


def fit_cv(bg_thumb: np.ndarray, thumb: np.ndarray, model: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The gate's photometric fit before the kernel: (the new 3 x 4 model, the float32 thumbnail); the
    least squares over the cells that fit ``model`` when at least half do, else over every cell."""
    y = thumb.astype(np.float32)
    _, inl, n = residual_cv(bg_thumb, y, model, tol)
    mask = inl if n >= inl.size // 2 else None
    mx, sx = cv2.meanStdDev(bg_thumb, mask=mask)
    my = cv2.mean(y, mask=mask)
    mxy = cv2.mean(cv2.multiply(bg_thumb, y), mask=mask)
    out = model.copy()
    for c, m, s in zip(range(3), mx[:, 0].tolist(), sx[:, 0].tolist()):
        var = s ** 2
        g = (mxy[c] - m * my[c]) / var if var > 1e-3 else 0.0
        out[c, c] = g
        out[c, 3] = my[c] - g * m
    return out, y


def residual_cv(bg_thumb: np.ndarray, thumb: np.ndarray, model: np.ndarray, tol: float
                ) -> tuple[np.ndarray, np.ndarray, int]:
    """(transform(bg_thumb, model), inRange(|thumb - it|, 0, tol) on every channel, its count): the
    gate's thumbnail fit before the kernel."""
    tmodel = cv2.transform(bg_thumb, model)
    inl = cv2.inRange(cv2.absdiff(thumb, tmodel), np.zeros(3), np.full(3, float(tol)))
    return tmodel, inl, cv2.countNonZero(inl)


class OracleFrameWork(FrameWork):
    """:class:`FrameWork` with every step done by the OpenCV calls (the gate before the kernels)."""

    def reduce(self, frame: np.ndarray, blur: bool = False, noise: bool = False) -> None:
        self.reduce_without_kernels(frame)  # noise: measured by noise() itself
        if blur:
            self.blur_small()

    def blur_small(self) -> None:
        b = self.blur
        if b > 1:
            cv2.GaussianBlur(self.small, (b, b), 0, dst=self.work)
        else:
            np.copyto(self.work, self.small)

    def noise(self, frame: np.ndarray) -> float:
        if self.sub is None:
            d = cv2.absdiff(self.small, self.work)
        else:
            cv2.resize(frame, (self.sub.shape[1], self.sub.shape[0]), dst=self.sub, interpolation=cv2.INTER_NEAREST)
            b = self.blur
            sb = cv2.GaussianBlur(self.sub, (b, b), 0) if b > 1 else self.sub.copy()
            d = cv2.absdiff(self.sub, sb)
        return float(max(cv2.mean(d)[:3]))

    def residual(self, bg_thumb: np.ndarray, thumb: np.ndarray, model: np.ndarray, tmodel: np.ndarray,
                 inl: np.ndarray, tol: np.float32) -> int:
        m, i, n = residual_cv(bg_thumb, thumb, model, float(tol))
        np.copyto(tmodel, m)
        np.copyto(inl, i)
        return n

    def fit(self, bg_thumb: np.ndarray, thumb: np.ndarray, y: np.ndarray, model: np.ndarray, tmodel: np.ndarray,
            inl: np.ndarray, tol: np.float32) -> None:
        self.residual(bg_thumb, thumb.astype(np.float32), model, tmodel, inl, tol)
        new, yf = fit_cv(bg_thumb, thumb, model, float(tol))
        np.copyto(model, new)
        np.copyto(y, yf)

    def contact_stats(self) -> tuple[int, float]:
        return cv2.countNonZero(self.mask), float(max(cv2.mean(self.ad, mask=self.mask)[:3]))

    def changed(self, bg: np.ndarray, model: np.ndarray) -> int:
        ad, mask = changed_cv(self.work, bg, model, self.threshold)
        np.copyto(self.ad, ad)
        np.copyto(self.mask, mask)
        return cv2.countNonZero(mask)


class OracleGate(ContactGate):
    """A :class:`ContactGate` whose per-frame image work is the OpenCV oracle."""

    frame_work = OracleFrameWork
