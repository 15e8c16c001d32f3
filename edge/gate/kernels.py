"""The contact gate's compiled per-frame kernels (numba; edge/gate/frame_work.py imports this module on
first use, so importing the package does not load numba).

The kernels see a frame's C-contiguous H x W x 3 buffer as H rows of W*3 uint8 values (horizontal
neighbours 3 apart) and loop over flat uint64 offsets (no negative-index checks), at unit stride, so
LLVM vectorises the loops; sums are int32 stored as uint8 or uint16, so it runs them in 16-bit lanes.
Each one equals the OpenCV calls it replaces bit for bit (tests/edge/gate/test_kernels.py holds those
calls as the oracle):

- :func:`reduce_blur`, one call per frame: ``area-2x-steps`` (log2(k) exact 2 x 2 box averages, each
  ``(a + b + c + d + 2) >> 2``, OpenCV ``INTER_AREA`` at exactly 1/2), computed over whole rows, the
  output keeping one value in k (:func:`_pick`: four pixels per three 32-bit stores where the
  addresses allow); the 3 x 3 Gaussian blur of the result (``cv2.GaussianBlur(src, (3, 3), 0)``:
  weights 1-2-1 x 1-2-1, ``(sum + 8) >> 4``, ``BORDER_REFLECT_101``, a band of rows at a time through a
  scratch of that many rows; :func:`blur3` alone); its
  thumbnail (:func:`shrink`: ``cv2.resize`` INTER_LINEAR at an even factor); where asked, the noise
  sums below.
- :func:`noise_sums`: the nearest subsample (``cv2.resize`` ``INTER_NEAREST`` at an integer factor:
  pixel (k y, k x)), its 3 x 3 blur, and the per-channel sums of |sub - blur|, the blur a band of
  rows at a time (no blurred image is kept).
- :func:`changed`: the model ``gain x background + offset`` (the product and sum in float64,
  rounded to float32 once, as ``cv2.transform`` of a float32 image by a diagonal matrix),
  ``convertScaleAbs`` (|x| rounded half to even, saturated; NaN and |x| >= 2^31 give 0 as its int32
  rounding does), ``absdiff`` and the mask 255 where any channel exceeds the integer bound.
- :func:`residual`: the thumbnail's photometric fit (``cv2.transform`` by the diagonal model,
  ``absdiff``, ``inRange`` within the tolerance, ``countNonZero``).
- :func:`fit_sums`: the sums the thumbnail's photometric fit needs (``cv2.meanStdDev`` and
  ``cv2.mean`` of the background, the frame and their product over the cells that fit), after
  :func:`residual` against the current model.
- :func:`masked_sums`: a contact mask's area and the sums of |frame - model| over it
  (``countNonZero`` and ``cv2.mean`` with the mask, whose sums are integers).
"""

from __future__ import annotations

import sys

import numpy as np

from ..compiled import compiled

_jit = compiled("contact gate kernels")
_inline = compiled("contact gate kernels", inline="always")


#: channels per pixel (BGR): a compile-time constant, so the horizontal neighbours' distance is known
_C = 3
#: 32-bit words hold their bytes lowest address first (every host numba runs on): :func:`_pick`
_LITTLE = sys.byteorder == "little"
#: offsets and counts of the flat loops: unsigned, so an index needs no negative-index check
_U = np.uint64


@_inline
def _step(src, a, b, d, m, dst, o):  # pragma: no cover - compiled
    """One 2 x 2 step of the rows at flat offsets ``a`` and ``b`` of ``src``, horizontal neighbours
    ``d`` apart: ``dst[o+i] = (src[a+i] + src[a+i+d] + src[b+i] + src[b+i+d] + 2) >> 2`` for i < m
    (uint8; the sums need 10 bits, so LLVM runs them in 16-bit lanes). Offsets are uint64: no
    negative-index checks."""
    for i in range(m):
        dst[o + i] = np.uint8((np.int32(src[a + i]) + np.int32(src[a + i + d]) + np.int32(src[b + i])
                               + np.int32(src[b + i + d]) + 2) >> 2)


@_inline
def _pick(src, src32, s, step, dst, dst32, o, w, wide):  # pragma: no cover - compiled
    """Pixel x < w of the row at flat offset ``o`` of ``dst`` = the 3 values at ``src[s + step*x:]``.
    With ``wide`` (``src32`` / ``dst32`` the same buffers as 32-bit words, ``s``, ``step`` and ``o``
    multiples of 4) four pixels at a time: four 32-bit loads, three 32-bit stores (little-endian);
    the rest one value at a time."""
    g = w // _U(4) if wide else _U(0)
    s4, st4, o4 = s // _U(4), step // _U(4), o // _U(4)
    for q in range(g):
        j = s4 + _U(4) * q * st4
        p0 = src32[j]
        p1 = src32[j + st4]
        p2 = src32[j + _U(2) * st4]
        p3 = src32[j + _U(3) * st4]
        k = o4 + _U(3) * q
        dst32[k] = (p0 & np.uint32(0xFFFFFF)) | (p1 << np.uint32(24))
        dst32[k + _U(1)] = ((p1 >> np.uint32(8)) & np.uint32(0xFFFF)) | (p2 << np.uint32(16))
        dst32[k + _U(2)] = ((p2 >> np.uint32(16)) & np.uint32(0xFF)) | (p3 << np.uint32(8))
    c = _U(_C)
    for x in range(_U(4) * g, w):
        j = s + step * x
        dst[o + c * x] = src[j]
        dst[o + c * x + _U(1)] = src[j + _U(1)]
        dst[o + c * x + _U(2)] = src[j + _U(2)]


@_jit
def _words(a):  # pragma: no cover - compiled
    """``a`` (C-contiguous uint8) flat and as 32-bit words (empty where its size or address is not a
    multiple of 4, or the host is big-endian: then :func:`_pick` goes one value at a time)."""
    flat = a.reshape(a.size)
    if _LITTLE and a.size % 4 == 0 and a.ctypes.data % 4 == 0:
        return flat, flat.view(np.uint32)
    return flat, np.empty(0, np.uint32)


@_inline
def _reduce_rows(f, n, y, k, v):  # pragma: no cover - compiled
    """Rows k*y .. k*y+k-1 of the frame (flat ``f``, rows of ``n`` values) reduced (log2(k) 2 x 2
    steps) into rows of the flat ``v`` (k rows of n uint8); returns the flat offset of the row
    where the value of output pixel x, channel ch ends, at 3*k*x + ch."""
    half = k // _U(2)
    m = n - _U(_C)
    for p in range(half):
        r = (k * y + _U(2) * p) * n
        _step(f, r, r + n, _U(_C), m, v, p * n)
    d = _U(2 * _C)
    src = _U(0)
    rows = half
    while rows > _U(1):
        dst = src + rows
        rows //= _U(2)
        m -= d
        for q in range(rows):
            _step(v, (src + _U(2) * q) * n, (src + _U(2) * q + _U(1)) * n, d, m, v, (dst + q) * n)
        src = dst
        d *= _U(2)
    return src * n


@_inline
def _g(left, mid, right):  # pragma: no cover - compiled
    """One blurred value from the vertical sums of three neighbours: (l + 2 m + r + 8) >> 4."""
    return np.uint8((np.int32(left) + 2 * np.int32(mid) + np.int32(right) + 8) >> 4)


@_inline
def _blur_band(x, n, h, y0, y1, t, out, o):  # pragma: no cover - compiled
    """Rows ``y0`` .. ``y1 - 1`` (a band: as many as ``t`` holds) of the 3 x 3 Gaussian blur of ``x``
    (flat, h rows of n = w*3 uint8, h and w >= 2) into ``out`` from flat offset ``o``, reflect-101
    edges: the vertical sums ``up + 2 mid + down`` of the rows into ``t`` (uint16), then the horizontal
    pass over all of them at once (a long loop: it vectorises); the values it mixes across a row's ends
    are then made again as the row's edges."""
    c = _U(_C)
    c2 = _U(2 * _C)
    hu = _U(h)
    base = y0 * n
    last = (hu - _U(1)) * n
    if y0 == _U(0):  # reflect-101: row -1 is row 1
        for i in range(n):
            t[i] = np.uint16(2 * np.int32(x[n + i]) + 2 * np.int32(x[i]))
    if y1 == hu:  # row h is row h-2
        q = last - base
        for i in range(n):
            t[q + i] = np.uint16(2 * np.int32(x[last - n + i]) + 2 * np.int32(x[last + i]))
    lo = max(y0, _U(1)) * n
    hi = min(y1, hu - _U(1)) * n
    for j in range(lo, hi):  # the rows inside: one long loop
        t[j - base] = np.uint16(np.int32(x[j - n]) + 2 * np.int32(x[j]) + np.int32(x[j + n]))
    size = (y1 - y0) * n
    for j in range(size - c2):
        out[o + j + c] = _g(t[j], t[j + c], t[j + c2])
    for q in range(_U(0), size, n):
        for ch in range(c):
            out[o + q + ch] = _g(t[q + ch + c], t[q + ch], t[q + ch + c])
            e = q + n - c + ch
            out[o + e] = _g(t[e - c], t[e], t[e - c])


@_jit
def _blur(x, n, h, t, out):  # pragma: no cover - compiled
    """The 3 x 3 Gaussian blur of ``x`` (flat, h rows of n = w*3 uint8, h and w >= 2) into ``out``
    (flat), reflect-101 edges, a band of rows at a time (:func:`_blur_band`; scratch ``t``: the band's
    vertical sums, b*n uint16 for b >= 1 rows)."""
    b = _U(t.shape[0]) // n
    for y0 in range(_U(0), _U(h), b):
        _blur_band(x, n, h, y0, min(y0 + b, _U(h)), t, out, y0 * n)


@_jit
def _noise(x, n, h, t, band, sums):  # pragma: no cover - compiled
    """Per-channel sums into ``sums`` (3 int64) of |x - blur(x)| (``x`` flat, h rows of n = w*3 uint8,
    h and w >= 2), a band of b rows at a time: their blur into ``band`` (b*n uint8), then the
    |difference| summed. Scratch: ``t`` (b*n uint16), ``band`` (b*n uint8), b >= 1: nothing of the
    image's size."""
    s0 = s1 = s2 = np.uint64(0)
    c = _U(_C)
    b = _U(min(t.shape[0], band.shape[0])) // n
    for y0 in range(_U(0), _U(h), b):
        y1 = min(y0 + b, _U(h))
        _blur_band(x, n, h, y0, y1, t, band, _U(0))
        r = y0 * n
        size = (y1 - y0) * n
        for j in range(size):
            band[j] = np.uint8(abs(np.int32(x[r + j]) - np.int32(band[j])))
        for j in range(size // c):
            s0 += np.uint64(band[c * j])
            s1 += np.uint64(band[c * j + _U(1)])
            s2 += np.uint64(band[c * j + _U(2)])
    sums[0], sums[1], sums[2] = s0, s1, s2


@_jit
def shrink(work, f, thumb):  # pragma: no cover - compiled
    """``thumb`` (h/f x w/f*3 uint8) = ``work`` (h x w*3) shrunk by the even integer ``f``, as
    ``cv2.resize`` INTER_LINEAR does at that factor: each value the two-by-two mean of the pixels
    around the cell's centre, (a + b + c + d + 2) >> 2."""
    th, tn = thumb.shape
    a = f // 2 - 1
    for y in range(th):
        r0 = work[f * y + a]
        r1 = work[f * y + a + 1]
        o = thumb[y]
        for x in range(tn // _C):
            j = _C * (f * x + a)
            for ch in range(_C):
                o[_C * x + ch] = np.uint8((np.int32(r0[j + ch]) + np.int32(r0[j + _C + ch]) + np.int32(r1[j + ch])
                                           + np.int32(r1[j + _C + ch]) + 2) >> 2)


@_jit
def reduce_blur(frame, k, small, work, sub, v, t, band, sums, tf, thumb):  # pragma: no cover - compiled
    """``frame`` (H x W*3 uint8) reduced by the power of two ``k`` >= 2 into ``small`` (H/k x W/k*3);
    when ``work`` has rows (h, w >= 2) its 3 x 3 Gaussian blur into ``work`` and, when ``thumb`` has
    rows, ``work`` shrunk by ``tf`` into it (:func:`shrink`); when ``sub`` has rows
    (k > 2, h, w >= 2) the nearest subsample (pixel (k y, k x)) into ``sub`` and the noise sums of
    :func:`noise_sums` into ``sums``, all in one call. Scratch: ``v`` (k x W*3 uint8), ``t`` and ``band`` (b
    >= 1 rows of the reduced image: b*W/k*3 uint16 and uint8: the blur's and the noise's band)."""
    h, mw = small.shape
    n = _U(frame.shape[1])
    w = _U(mw // _C)
    ku = _U(k)
    step = _U(_C) * ku
    f, f32 = _words(frame)
    vf, v32 = _words(v)
    sf, s32 = _words(small)
    noise = sub.shape[0] > 0
    bf, b32 = _words(sub)
    wide = step % _U(4) == _U(0) and n % _U(4) == _U(0) and _U(mw) % _U(4) == _U(0)
    for y in range(_U(h)):
        last = _reduce_rows(f, n, y, ku, vf)
        _pick(vf, v32, last, step, sf, s32, y * _U(mw), w, wide and v32.size > 0 and s32.size > 0)
        if noise:
            _pick(f, f32, ku * y * n, step, bf, b32, y * _U(mw), w, wide and f32.size > 0 and b32.size > 0)
    if work.shape[0] > 0:
        _blur(sf, _U(mw), h, t, work.reshape(work.size))
        if thumb.shape[0] > 0:
            shrink(work, tf, thumb)
    if noise:
        _noise(bf, _U(mw), h, t, band, sums)


@_jit
def noise_sums(frame, k, sub, t, band, sums):  # pragma: no cover - compiled
    """Per-channel sums into ``sums`` (3 int64) of |sub - blur(sub)|, ``sub`` the nearest subsample of
    ``frame`` (pixel (k y, k x), into ``sub``: h x w*3 uint8, h and w >= 2), blur the 3 x 3 Gaussian.
    Scratch: ``t`` (b*w*3 uint16), ``band`` (b*w*3 uint8), b >= 1 rows."""
    h, mw = sub.shape
    n = _U(frame.shape[1])
    step = _U(_C * k)
    f, f32 = _words(frame)
    bf, b32 = _words(sub)
    wide = step % _U(4) == _U(0) and n % _U(4) == _U(0) and _U(mw) % _U(4) == _U(0) and f32.size > 0 \
        and b32.size > 0
    for y in range(_U(h)):
        _pick(f, f32, _U(k) * y * n, step, bf, b32, y * _U(mw), _U(mw // _C), wide)
    _noise(bf, _U(mw), h, t, band, sums)


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
    lim = np.int32(ub)
    count = np.int32(0)
    for y in range(h):
        src = bg[y]
        wr = work[y]
        a = ad[y]
        mk = mask[y]
        for i in range(n):  # float32 lanes after the model: |x| rounded and saturated is a whole number
            r = np.rint(abs(np.float32(np.float64(src[i]) * gt[i] + ot[i])))
            q = np.float32(255.0) if r > np.float32(255.0) else r
            # convertScaleAbs rounds to int32 first: NaN and |x| >= 2^31 give INT_MIN, saturated to 0
            q = q if r < np.float32(2147483648.0) else np.float32(0.0)
            a[i] = np.uint8(abs(np.float32(wr[i]) - q))
        for x in range(w):  # without branches: LLVM vectorises the stride-3 reads
            hit = np.int32((np.int32(a[_C * x]) > lim) | (np.int32(a[_C * x + 1]) > lim)
                           | (np.int32(a[_C * x + 2]) > lim))
            mk[x] = np.uint8(255 * hit)
            count += hit
    return count


@_jit
def residual(bg, model, thumb, tmodel, inl, tol):  # pragma: no cover - compiled
    """The thumbnail's fit to the model: ``tmodel`` = gain x ``bg`` + offset per channel (``model``
    the 3 x 4 float32 matrix, diagonal and last column read; the product and sum in float64 rounded
    to float32 once, as ``cv2.transform`` by a diagonal matrix), ``inl`` (rows x cols uint8) 255 where
    |thumb - tmodel| (float32, ``cv2.absdiff``) lies within [0, ``tol``] on every channel (``cv2.inRange``
    with the bounds as float32: NaN is out), else 0; returns the count of 255 cells. ``bg``,
    ``thumb``, ``tmodel``: rows x cols x 3 float32."""
    b = bg.reshape(bg.size)
    y = thumb.reshape(thumb.size)
    m = tmodel.reshape(tmodel.size)
    out = inl.reshape(inl.size)
    zero = np.float32(0.0)
    count = 0
    for x in range(out.shape[0]):
        ok = True
        for ch in range(_C):
            j = _C * x + ch
            v = np.float32(np.float64(b[j]) * np.float64(model[ch, ch]) + np.float64(model[ch, 3]))
            m[j] = v
            d = abs(y[j] - v)
            ok = ok and zero <= d and d <= tol
        out[x] = np.uint8(255) if ok else np.uint8(0)
        count += 1 if ok else 0
    return count


@_jit
def masked_sums(mask, ad, sums):  # pragma: no cover - compiled
    """The count of nonzero pixels of ``mask`` (h x w uint8) and into ``sums`` (3 int64) the
    per-channel sums of ``ad`` (h x w x 3 uint8) over them: ``cv2.countNonZero`` and the sums
    ``cv2.mean(ad, mask)`` divides by that count. Without branches: each value times 0 or 1."""
    m = mask.reshape(mask.size)
    a = ad.reshape(ad.size)
    c3 = _U(_C)
    count = s0 = s1 = s2 = np.int64(0)
    for p in range(_U(m.shape[0])):
        on = np.int64(m[p] != 0)
        count += on
        s0 += on * np.int64(a[c3 * p])
        s1 += on * np.int64(a[c3 * p + _U(1)])
        s2 += on * np.int64(a[c3 * p + _U(2)])
    sums[0], sums[1], sums[2] = s0, s1, s2
    return count


@_jit
def fit_sums(bg, thumb, y, model, tmodel, inl, tol, sums):  # pragma: no cover - compiled
    """The sums of the thumbnail's photometric fit: ``y`` = ``thumb`` as float32 (rows x cols x 3;
    ``thumb`` uint8), the fit of :func:`residual` to the current ``model`` into ``tmodel`` and
    ``inl``; then, when at least half the cells fit, over those cells per channel c: ``sums[c]`` =
    the sum of ``bg``, ``sums[3 + c]`` of its squares, ``sums[6 + c]`` of ``y``, ``sums[9 + c]`` of
    the float32 product ``bg`` x ``y``, in float64 cell by cell (as ``cv2.meanStdDev`` and
    ``cv2.mean`` with a mask add them), ``sums[12]`` the count (else ``sums`` is left as it was).
    Returns the count of cells that fit the current model."""
    yf = y.reshape(y.size)
    t = thumb.reshape(thumb.size)
    for j in range(yf.shape[0]):
        yf[j] = np.float32(t[j])
    fit = residual(bg, model, y, tmodel, inl, tol)
    if fit < inl.size // 2:
        return fit
    b = bg.reshape(bg.size)
    mk = inl.reshape(inl.size)
    for k in range(13):
        sums[k] = 0.0
    for x in range(mk.shape[0]):
        if mk[x] == 0:
            continue
        sums[12] += 1.0
        for ch in range(_C):
            v = b[_C * x + ch]
            w = yf[_C * x + ch]
            vd = np.float64(v)
            sums[ch] += vd
            sums[3 + ch] += vd * vd
            sums[6 + ch] += np.float64(w)
            sums[9 + ch] += np.float64(v * w)
    return fit


@_jit
def blur3(small, t, work):  # pragma: no cover - compiled
    """The 3 x 3 Gaussian blur of ``small`` (h x w*3 uint8, h and w >= 2) into ``work``; scratch ``t``
    (b >= 1 rows: b*w*3 uint16)."""
    h, mw = small.shape
    _blur(small.reshape(small.size), _U(mw), h, t, work.reshape(work.size))


def warm() -> None:
    """Load every kernel (compile it on the first run of an environment, else from numba's cache)
    for the argument types the gate passes, writable and read-only frames, so that no frame
    waits for it."""
    frame = np.zeros((8, 24), np.uint8)
    small, work, sub = (np.zeros((2, 6), np.uint8) for _ in range(3))
    v, t, band = np.zeros((4, 24), np.uint8), np.zeros(6, np.uint16), np.zeros(6, np.uint8)
    sums = np.zeros(3, np.int64)
    model = np.zeros((3, 4), np.float32)
    read_only = frame.copy()
    read_only.setflags(write=False)  # a read-only frame is another compiled form
    for f in (frame, read_only):
        reduce_blur(f, 4, small, work, sub, v, t, band, sums, 2, small[:1, :3])
        reduce_blur(f, 4, small, work[:0], sub[:0], v, t, band, sums, 2, small[:0])
        noise_sums(f, 4, sub, t, band, sums)
    blur3(small, t, work)
    changed(np.zeros((2, 6), np.float32), model, work, small, np.zeros((2, 2), np.uint8), 10, np.zeros(6),
            np.zeros(6))
    thumb = np.zeros((2, 2, 3), np.float32)
    residual(thumb, model, thumb, thumb.copy(), np.zeros((2, 2), np.uint8), np.float32(8.0))
    masked_sums(np.zeros((2, 2), np.uint8), np.zeros((2, 2, 3), np.uint8), sums)
    fit_sums(thumb, np.zeros((2, 2, 3), np.uint8), thumb.copy(), model, thumb.copy(), np.zeros((2, 2), np.uint8),
             np.float32(8.0), np.zeros(13))
