"""The contact gate's compiled per-frame kernels (numba; edge/gate/frame_work.py imports this module on
first use, so importing the package does not load numba).

Every kernel works on H x (W*3) uint8 rows (a frame's C-contiguous H x W x 3 buffer seen as 2-D), so
its inner loops run at unit stride and LLVM vectorises them (no loop writes the array it reads;
uint32 arithmetic, no shifts of small types); horizontal neighbours are 3 apart. Each
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

import numpy as np

from ..compiled import compiled

_jit = compiled("contact gate kernels")


#: channels per pixel (BGR): a compile-time constant, so the horizontal neighbours' distance is known
_C = 3


@_jit
def _reduce_rows(frame, y, k, v):  # pragma: no cover - compiled
    """Rows k*y .. k*y+k-1 of ``frame`` reduced into rows of ``v`` (k x W*3 uint16); returns the row
    where the value of output pixel x, channel ch ends, at index 3*k*x + ch. No loop writes the
    array it reads (so each one vectorises)."""
    n = frame.shape[1]
    half = k // 2
    tmp = v[k - 1]
    for p in range(half):  # first step: vertical pair sums, then horizontal pairs (3 apart)
        r0 = frame[k * y + 2 * p]
        r1 = frame[k * y + 2 * p + 1]
        for i in range(n):
            tmp[i] = np.uint16(np.uint32(r0[i]) + np.uint32(r1[i]))
        vv = v[p]
        for i in range(n - _C):
            vv[i] = np.uint16((np.uint32(tmp[i]) + np.uint32(tmp[i + _C]) + np.uint32(2)) >> np.uint32(2))
    d = 2 * _C
    src = 0
    rows = half
    while rows > 1:  # further steps: 2 x 2 of the previous step's values, d apart, into new rows
        dst = src + rows
        rows //= 2
        for q in range(rows):
            a = v[src + 2 * q]
            b = v[src + 2 * q + 1]
            a_d = a[d:]  # views d ahead: indices that cannot be negative, so no wrap-around check
            b_d = b[d:]
            o = v[dst + q]
            for i in range(n - d):
                o[i] = np.uint16((np.uint32(a[i]) + np.uint32(a_d[i]) + np.uint32(b[i]) + np.uint32(b_d[i])
                                  + np.uint32(2)) >> np.uint32(2))
        src = dst
        d *= 2
    return src


@compiled("contact gate kernels", inline="always")
def _g(left, mid, right):  # pragma: no cover - compiled
    """One blurred value from the vertical sums of three neighbours: (l + 2 m + r + 8) >> 4."""
    return np.uint8((np.uint32(left) + np.uint32(2) * np.uint32(mid) + np.uint32(right) + np.uint32(8)) >> np.uint32(4))


@_jit
def _blur_row(small, y, t, out):
    """Row y of the 3 x 3 Gaussian blur of ``small`` (h x (w*3), h and w >= 2) into ``out``."""
    h, n = small.shape
    up = small[y - 1 if y > 0 else 1]
    mid = small[y]
    dn = small[y + 1 if y < h - 1 else h - 2]
    for i in range(n):
        t[i] = np.uint16(np.uint32(up[i]) + np.uint32(2) * np.uint32(mid[i]) + np.uint32(dn[i]))
    t_1 = t[_C:]  # views 3 and 6 ahead (indices that cannot be negative: the loop vectorises)
    t_2 = t[2 * _C:]
    o_1 = out[_C:]
    for i in range(n - 2 * _C):
        o_1[i] = _g(t[i], t_1[i], t_2[i])
    for ch in range(_C):  # reflect-101 edges: the neighbour outside is the one inside
        out[ch] = _g(t[ch + _C], t[ch], t[ch + _C])
        j = n - _C + ch
        out[j] = _g(t[j - _C], t[j], t[j - _C])


@_jit
def reduce_blur(frame, k, small, work, v, t):  # pragma: no cover - compiled
    """``frame`` (H x W*3 uint8) reduced by the power of two ``k`` >= 2 into ``small`` (H/k x W/k*3)
    and, when ``work`` has rows (h, w >= 2), its 3 x 3 Gaussian blur into ``work``.
    Scratch: ``v`` (k x W*3 uint16), ``t`` (W/k*3 uint16)."""
    h, m = small.shape
    step = _C * k
    for y in range(h):
        last = v[_reduce_rows(frame, y, k, v)]
        o = small[y]
        for x in range(m // _C):
            j = step * x
            o[_C * x] = last[j]
            o[_C * x + 1] = last[j + 1]
            o[_C * x + 2] = last[j + 2]
    if work.shape[0] > 0:
        for y in range(h):
            _blur_row(small, y, t, work[y])


@_jit
def noise_sums(frame, k, sub, t, b, acc, sums):  # pragma: no cover - compiled
    """Per-channel sums into ``sums`` (3 int64) of |sub - blur(sub)|, ``sub`` the nearest subsample of
    ``frame`` (pixel (k y, k x), into ``sub``: h x w*3 uint8, h and w >= 2), blur the 3 x 3 Gaussian.
    Scratch: ``t``, ``b`` (w*3 uint16), ``acc`` (w*3 uint32)."""
    h, n = sub.shape
    w = n // _C
    step = _C * k
    for y in range(h):
        r = frame[k * y]
        s = sub[y]
        for x in range(w):
            j = step * x
            s[_C * x] = r[j]
            s[_C * x + 1] = r[j + 1]
            s[_C * x + 2] = r[j + 2]
    for i in range(n):
        acc[i] = 0
    for y in range(h):
        _blur_row(sub, y, t, b)
        s = sub[y]
        for i in range(n):
            a = np.int32(s[i]) - np.int32(b[i])
            acc[i] += np.uint32(a if a >= 0 else -a)
    s0 = s1 = s2 = 0
    for x in range(w):
        s0 += acc[_C * x]
        s1 += acc[_C * x + 1]
        s2 += acc[_C * x + 2]
    sums[0], sums[1], sums[2] = s0, s1, s2


@_jit
def changed(bg, model, work, ad, mask, ub, gt, ot):  # pragma: no cover - compiled
    """|work - u8(gain x bg + offset)| into ``ad`` (h x w*3 uint8) and 255 into ``mask`` (h x w) where a
    channel of it exceeds ``ub`` (0 elsewhere); returns the count of 255 pixels. ``bg`` h x w*3
    float32; ``model`` the 3 x 4 float32 matrix, diagonal (gain) and last column (offset) read: the model
    is computed in float64 and rounded to float32 once, as ``cv2.transform`` of a float32 image by a
    diagonal matrix does. Scratch: ``gt``, ``ot`` (w*3 float64: gain and offset per value of a row)."""
    h, n = work.shape
    w = n // _C
    for x in range(w):
        for ch in range(_C):
            gt[_C * x + ch] = np.float64(model[ch, ch])
            ot[_C * x + ch] = np.float64(model[ch, 3])
    lim = np.uint32(ub)
    count = 0
    for y in range(h):
        src = bg[y]
        wr = work[y]
        a = ad[y]
        mk = mask[y]
        for i in range(n):
            m = abs(np.float32(np.float64(src[i]) * gt[i] + ot[i]))
            q = np.int32(np.minimum(np.rint(m), np.float32(255.0)))
            a[i] = np.uint8(abs(np.int32(wr[i]) - q))
        for x in range(w):
            hit = max(np.uint32(a[_C * x]), np.uint32(a[_C * x + 1]), np.uint32(a[_C * x + 2])) > lim
            mk[x] = np.uint8(255) if hit else np.uint8(0)
            count += np.int64(hit)
    return count


@_jit
def blur3(small, t, work):  # pragma: no cover - compiled
    """The 3 x 3 Gaussian blur of ``small`` (h x w*3 uint8, h and w >= 2) into ``work``; scratch ``t``
    (w*3 uint16)."""
    for y in range(small.shape[0]):
        _blur_row(small, y, t, work[y])


def warm() -> None:
    """Load every kernel (compile it on the first run of an environment, else from numba's cache)
    for the argument types the gate passes, writable and read-only frames, so that no frame
    waits for it."""
    frame = np.zeros((4, 12), np.uint8)
    small, work = np.zeros((2, 6), np.uint8), np.zeros((2, 6), np.uint8)
    v, t = np.zeros((2, 12), np.uint16), np.zeros(6, np.uint16)
    acc, sums = np.zeros(6, np.uint32), np.zeros(3, np.int64)
    model = np.zeros((3, 4), np.float32)
    read_only = frame.copy()
    read_only.setflags(write=False)  # a read-only frame is another compiled form
    for f in (frame, read_only):
        reduce_blur(f, 2, small, work, v, t)
        reduce_blur(f, 2, small, work[:0], v, t)
        noise_sums(f, 2, small, t, t.copy(), acc, sums)
    blur3(small, t, work)
    changed(np.zeros((2, 6), np.float32), model, work, small, np.zeros((2, 2), np.uint8), 10, np.zeros(6),
            np.zeros(6))
