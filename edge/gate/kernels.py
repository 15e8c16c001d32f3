"""The contact gate's compiled per-frame kernels (numba; edge/gate/frame_work.py imports this module on
first use, so importing the package does not load numba).

Every kernel works on H x (W*C) uint8 rows (a frame's C-contiguous H x W x C buffer seen as 2-D), so
its inner loops run at unit stride and LLVM vectorises them; horizontal neighbours are C apart. Each
one equals the OpenCV calls it replaces bit for bit (tests/edge/gate/test_kernels.py holds those
calls as the oracle):

- :func:`reduce_blur`: ``area-2x-steps`` (log2(k) exact 2 x 2 box averages, each
  ``(a + b + c + d + 2) >> 2``, OpenCV ``INTER_AREA`` at exactly 1/2) and the 3 x 3 Gaussian blur of
  the result (``cv2.GaussianBlur(src, (3, 3), 0)``: weights 1-2-1 x 1-2-1, ``(sum + 8) >> 4``,
  ``BORDER_REFLECT_101``); :func:`blur3` the blur alone.
- :func:`noise_sums`: the nearest subsample (``cv2.resize`` ``INTER_NEAREST`` at an integer factor:
  pixel (k y, k x)), its 3 x 3 blur, and the per-channel sums of |sub - blur|.
- :func:`changed`: the model ``gain x background + offset`` (the product and sum in float64,
  rounded to float32 once, as ``cv2.transform`` of a float32 image by a diagonal matrix),
  ``convertScaleAbs`` (|x| rounded half to even, saturated), ``absdiff`` and the mask 255 where
  any channel exceeds the integer bound.
"""

from __future__ import annotations

import numba as nb
import numpy as np

_jit = nb.njit(cache=True, nogil=True, boundscheck=False)


@_jit
def _reduce_rows(frame, y, k, c, v):  # pragma: no cover - compiled
    """Rows k*y .. k*y+k-1 of ``frame`` reduced in place into v[0]: the value of output pixel x,
    channel ch ends at index c*k*x + ch."""
    n = frame.shape[1]
    half = k // 2
    for p in range(half):  # first step: vertical pair sums, then horizontal pairs (C apart)
        r0 = frame[k * y + 2 * p]
        r1 = frame[k * y + 2 * p + 1]
        vv = v[p]
        for i in range(n):
            vv[i] = np.uint16(r0[i]) + np.uint16(r1[i])
        for i in range(n - c):
            vv[i] = (vv[i] + vv[i + c] + np.uint16(2)) >> np.uint16(2)
    d = 2 * c
    rows = half
    while rows > 1:  # further steps: 2 x 2 of the previous step's values, d apart
        rows //= 2
        for q in range(rows):
            a = v[2 * q]
            b = v[2 * q + 1]
            o = v[q]
            for i in range(n - d):
                o[i] = (a[i] + a[i + d] + b[i] + b[i + d] + np.uint16(2)) >> np.uint16(2)
        d *= 2


@_jit
def _blur_row(small, y, c, t, out):  # pragma: no cover - compiled
    """Row y of the 3 x 3 Gaussian blur of ``small`` (h x (w*c), h and w >= 2) into ``out``."""
    h, n = small.shape
    up = small[y - 1 if y > 0 else 1]
    mid = small[y]
    dn = small[y + 1 if y < h - 1 else h - 2]
    for i in range(n):
        t[i] = np.uint16(up[i]) + (np.uint16(mid[i]) << np.uint16(1)) + np.uint16(dn[i])
    for i in range(c, n - c):
        out[i] = (t[i - c] + (t[i] << np.uint16(1)) + t[i + c] + np.uint16(8)) >> np.uint16(4)
    for ch in range(c):  # reflect-101 edges: the neighbour outside is the one inside
        out[ch] = (t[ch + c] + (t[ch] << np.uint16(1)) + t[ch + c] + np.uint16(8)) >> np.uint16(4)
        j = n - c + ch
        out[j] = (t[j - c] + (t[j] << np.uint16(1)) + t[j - c] + np.uint16(8)) >> np.uint16(4)


@_jit
def reduce_blur(frame, k, c, small, work, v, t):  # pragma: no cover - compiled
    """``frame`` (H x W*c uint8) reduced by the power of two ``k`` >= 2 into ``small`` (H/k x W/k*c)
    and, when ``work`` has rows (h, w >= 2), its 3 x 3 Gaussian blur into ``work``.
    Scratch: ``v`` (k/2 x W*c uint16), ``t`` (W/k*c uint16)."""
    h, m = small.shape
    v0 = v[0]
    step = c * k
    for y in range(h):
        _reduce_rows(frame, y, k, c, v)
        o = small[y]
        for x in range(m // c):
            j = step * x
            for ch in range(c):
                o[c * x + ch] = v0[j + ch]
    if work.shape[0] > 0:
        for y in range(h):
            _blur_row(small, y, c, t, work[y])


@_jit
def noise_sums(frame, k, c, sub, t, b, acc, sums):  # pragma: no cover - compiled
    """Per-channel sums into ``sums`` (c int64) of |sub - blur(sub)|, ``sub`` the nearest subsample of
    ``frame`` (pixel (k y, k x), into ``sub``: h x w*c uint8, h and w >= 2), blur the 3 x 3 Gaussian.
    Scratch: ``t``, ``b`` (w*c uint16), ``acc`` (w*c uint32)."""
    h, n = sub.shape
    w = n // c
    for y in range(h):
        r = frame[k * y]
        s = sub[y]
        for x in range(w):
            for ch in range(c):
                s[c * x + ch] = r[c * k * x + ch]
    for i in range(n):
        acc[i] = 0
    for y in range(h):
        _blur_row(sub, y, c, t, b)
        s = sub[y]
        for i in range(n):
            a = np.int32(s[i]) - np.int32(b[i])
            acc[i] += np.uint32(a if a >= 0 else -a)
    for ch in range(c):
        sums[ch] = 0
    for x in range(w):
        for ch in range(c):
            sums[ch] += acc[c * x + ch]


@_jit
def changed(bg, model, work, ad, mask, ub):  # pragma: no cover - compiled
    """|work - u8(gain x bg + offset)| into ``ad`` (h x w*3 uint8) and 255 into ``mask`` (h x w) where a
    channel of it exceeds ``ub`` (0 elsewhere); returns the count of 255 pixels. ``bg`` h x w*3
    float32; ``model`` the 3 x 4 float32 matrix, diagonal (gain) and last column (offset) read: the model
    is computed in float64 and rounded to float32 once, as ``cv2.transform`` of a float32 image by a
    diagonal matrix does."""
    h, n = work.shape
    w = n // 3
    g0, g1, g2 = np.float64(model[0, 0]), np.float64(model[1, 1]), np.float64(model[2, 2])
    o0, o1, o2 = np.float64(model[0, 3]), np.float64(model[1, 3]), np.float64(model[2, 3])
    lim = np.uint8(ub)
    count = 0
    for y in range(h):
        src = bg[y]
        wr = work[y]
        a = ad[y]
        mk = mask[y]
        for x in range(w):
            j = 3 * x
            hit = False
            for ch in range(3):
                g = g0 if ch == 0 else (g1 if ch == 1 else g2)
                o = o0 if ch == 0 else (o1 if ch == 1 else o2)
                m = abs(np.float32(np.float64(src[j + ch]) * g + o))
                q = np.uint8(255) if m >= np.float32(255.0) else np.uint8(np.rint(m))
                p = wr[j + ch]
                d = p - q if p > q else q - p
                a[j + ch] = d
                hit = hit or d > lim
            mk[x] = np.uint8(255) if hit else np.uint8(0)
            count += 1 if hit else 0
    return count


@_jit
def blur3(small, c, t, work):  # pragma: no cover - compiled
    """The 3 x 3 Gaussian blur of ``small`` (h x w*c uint8, h and w >= 2) into ``work``; scratch ``t``
    (w*c uint16)."""
    for y in range(small.shape[0]):
        _blur_row(small, y, c, t, work[y])


def warm() -> None:
    """Load every kernel (compile it on the first run of an environment, else from numba's cache)
    for the argument types the gate passes, writable and read-only frames, so that no frame
    waits for it."""
    frame = np.zeros((4, 12), np.uint8)
    small, work = np.zeros((2, 6), np.uint8), np.zeros((2, 6), np.uint8)
    v, t = np.zeros((1, 12), np.uint16), np.zeros(6, np.uint16)
    acc, sums = np.zeros(6, np.uint32), np.zeros(3, np.int64)
    model = np.zeros((3, 4), np.float32)
    read_only = frame.copy()
    read_only.setflags(write=False)  # a read-only frame is another compiled form
    for f in (frame, read_only):
        reduce_blur(f, 2, 3, small, work, v, t)
        reduce_blur(f, 2, 3, small, work[:0], v, t)
        noise_sums(f, 2, 3, small, t, t.copy(), acc, sums)
    blur3(small, 3, t, work)
    changed(np.zeros((2, 6), np.float32), model, work, small, np.zeros((2, 2), np.uint8), 10)
