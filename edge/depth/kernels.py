"""The depth stage's compiled per-frame kernels at network resolution (numba; edge/depth/stage.py
imports this module when it builds a stage that uses them, so importing the package does not load
numba).

They serve the shipped compact depth bundles' path: a ``calibrate-depth`` LUT, exact mode, a
downscale k > 1, float32 solver, the gate's reduced image and uint8 mask. Each does, in one call,
what a chain of OpenCV and numpy calls did, with the same float32 operations in the same order (no
fastmath: LLVM neither reorders nor fuses them), so the results are equal bit for bit, signed
zeros included; tests/edge/depth/oracle.py keeps that chain as the test oracle:

- :func:`gradients_divergence`: the contact pixels (mask != 0), those with a channel at 255 and
  the mask's bounding box (``cv2.countNonZero``, ``cv2.inRange`` + ``cv2.bitwise_and``,
  ``cv2.boundingRect``); then colour difference -> LUT cell -> guarded gradient (x k) inside the
  box, times the 0/1 mask; the mean slope of each forward difference; the backward-difference
  divergence on the interior (what the Poisson solver's DST-I products read).
- :func:`depth_image`: the solved interior into the height map (zero first row and column), the
  finite check, and ``rint(clip(h * levels_per_px, 0, 255) * mask)`` as uint8.

The DST-I products between them stay numpy's (OpenBLAS sgemm on the same operands).
"""

from __future__ import annotations

import numpy as np

from ..compiled import compiled

_compiled = compiled("depth stage kernels")


@_compiled
def _mask_stats(frame, mask, colany, box):  # pragma: no cover - compiled
    """Contact pixels (``mask`` != 0), those with a channel of ``frame`` at 255, and the mask's
    bounding box into ``box`` (row0, row1, col0, col1; ends exclusive). ``colany``: w uint8 scratch."""
    h, w = mask.shape
    n = 0
    sat = 0
    r0, r1 = h, 0
    for x in range(w):
        colany[x] = 0
    for y in range(h):
        mk = mask[y]
        k = 0
        for x in range(w):
            k += np.int64(mk[x] != 0)
        if k == 0:
            continue
        n += k
        if y < r0:
            r0 = y
        r1 = y + 1
        for x in range(w):
            colany[x] |= mk[x]
        fr = frame[y]
        full = np.uint8(0)
        for i in range(3 * w):
            full |= np.uint8(fr[i] == 255)
        if full != 0:  # a channel at 255 in this row: count the contact pixels that hold one
            for x in range(w):
                hit = (fr[3 * x] == 255) | (fr[3 * x + 1] == 255) | (fr[3 * x + 2] == 255)
                sat += np.int64(hit & (mk[x] != 0))
    c0, c1 = w, 0
    for x in range(w):
        if colany[x] != 0:
            if x < c0:
                c0 = x
            c1 = x + 1
    box[0], box[1], box[2], box[3] = r0, r1, c0, c1
    return n, sat


@_compiled
def gradients_divergence(frame, mask, bg, glut, work, div, scratch, inv_width, top, bins,
                         saturated_fraction):  # pragma: no cover - compiled
    """The contact checks, then the gradients of the mask's pixels and the divergence the solver
    transforms.

    ``frame`` h x (w*3) uint8; ``mask`` h x w uint8 (in: != 0); ``bg`` h x (w*3) float32 background
    minus half the LUT's span; ``glut`` (2 bins^3,) float32 guarded gradients x k per cell (gx, gy
    interleaved); ``work`` (2, h, w) float32 scratch (gx, gy); ``div`` (h-1) x (w-1) float32 out;
    ``scratch`` int64, at least 4 + 3 w long; ``inv_width`` float32 1 / bin width; ``top`` float32 bins - 1.

    Returns (contact pixels, contact pixels with a channel at 255); ``div`` is written only when
    there is contact and at most ``saturated_fraction`` of it is saturated. Inside the mask's box a
    gradient is ``glut[cell] * (1.0 or 0.0)`` (the mask as 0/1), outside +0; then
    ``g[:, j] = (g[:, j] + g[:, j+1]) * 0.5`` (``gy`` along rows; the last column / row
    ``g * 0.5``) and ``div = ((gx[1:, 1:] - gx[1:, :-1]) + gy[1:, 1:]) - gy[:-1, 1:]``.
    """
    h, w = mask.shape
    box = scratch[:4]
    colany = scratch[4:4 + w].view(np.uint8)[:w]
    qi = scratch[4 + w:].view(np.int32)  # a row's bins (int32: the conversions vectorise)
    n, sat = _mask_stats(frame, mask, colany, box)
    if n == 0 or sat > saturated_fraction * n:
        return n, sat
    r0, r1, c0, c1 = box[0], box[1], box[2], box[3]
    gx = work[0]
    gy = work[1]
    zero = np.float32(0.0)
    one = np.float32(1.0)
    half = np.float32(0.5)
    b = np.uint32(bins)
    for y in range(h):
        ox = gx[y]
        oy = gy[y]
        for x in range(w):
            ox[x] = zero
            oy[x] = zero
    nb = c1 - c0
    for y in range(r0, r1):
        fr = frame[y][3 * c0:3 * c1]  # views from the box's first column: indices from 0
        bgr = bg[y][3 * c0:3 * c1]
        for i in range(3 * nb):  # each channel's bin: clip((f - bg) / width, 0, bins - 1), floored
            q = (np.float32(fr[i]) - bgr[i]) * inv_width
            q = q if q >= zero else zero  # never NaN: a uint8 minus a finite float32
            q = q if q <= top else top
            qi[i] = np.int32(np.floor(q))
        mk = mask[y][c0:c1]
        ox = gx[y][c0:c1]
        oy = gy[y][c0:c1]
        for x in range(nb):  # the cell (q0 b + q1) b + q2 and its gradients x (1.0 or 0.0)
            cell = (np.uint32(qi[3 * x]) * b + np.uint32(qi[3 * x + 1])) * b + np.uint32(qi[3 * x + 2])
            inside = one if mk[x] != 0 else zero
            ox[x] = glut[np.uint32(2) * cell] * inside
            oy[x] = glut[np.uint32(2) * cell + np.uint32(1)] * inside
    # Beyond rows r0 - 2 .. r1 and columns c0 - 2 .. c1 every gradient is +0, so the mean slopes
    # and the divergence are +0 there, as the full pass gives: the passes cover that window only.
    y0, y1 = max(r0 - 2, 0), min(r1 + 1, h)
    x0, x1 = max(c0 - 2, 0), min(c1 + 1, w)
    for i in range(h - 1):
        d = div[i]
        for j in range(w - 1):
            d[j] = zero
    nx_ = x1 - x0  # (loops index views from 0: no wrap-around checks, so they vectorise)
    for y in range(y0, y1):  # the mean slope of each forward difference (x: along the row)
        ox = gx[y][x0:x1]
        ox1 = gx[y][x0 + 1:x1]
        for x in range(nx_ - 1):
            ox[x] = (ox[x] + ox1[x]) * half
        ox[nx_ - 1] = ox[nx_ - 1] * half if x1 == w else (ox[nx_ - 1] + gx[y][x1]) * half
    for y in range(y0, y1 - 1):  # (y: down the rows; row y + 1 still holds its own slopes)
        oy = gy[y][x0:x1]
        ny = gy[y + 1][x0:x1]
        for x in range(nx_):
            oy[x] = (oy[x] + ny[x]) * half
    last = gy[y1 - 1][x0:x1]
    ny = gy[min(y1, h - 1)][x0:x1]
    for x in range(nx_):
        last[x] = last[x] * half if y1 == h else (last[x] + ny[x]) * half
    j0, j1 = max(x0 - 1, 0), min(x1, w - 1)
    for i in range(max(y0 - 1, 0), min(y1, h - 1)):
        d = div[i][j0:j1]
        a = gx[i + 1][j0:j1]
        a1 = gx[i + 1][j0 + 1:j1 + 1]
        u1 = gy[i + 1][j0 + 1:j1 + 1]
        v1 = gy[i][j0 + 1:j1 + 1]
        for j in range(j1 - j0):
            d[j] = ((a1[j] - a[j]) + u1[j]) - v1[j]
    return n, sat


@_compiled
def depth_image(interior, mask, levels_per_px, height, depth):  # pragma: no cover - compiled
    """``height`` (h x w float32) = 0 on row 0 and column 0, ``interior`` ((h-1) x (w-1) float32)
    elsewhere; ``depth`` (h x w uint8) = ``rint(min(max(height * levels_per_px, 0), 255) * m)``,
    m = 1.0 where ``mask`` != 0 else 0.0 (``levels_per_px`` float32). Returns False (depth then
    unspecified) when a height is not finite."""
    h, w = height.shape
    zero = np.float32(0.0)
    one = np.float32(1.0)
    top = np.float32(255.0)
    worst = np.uint32(0)
    for x in range(w):
        height[0, x] = zero
    for y in range(1, h):
        hr = height[y]
        src = interior[y - 1]
        hr[0] = zero
        h1 = hr[1:]
        for x in range(w - 1):
            h1[x] = src[x]
        bits = hr.view(np.uint32)
        for x in range(w):  # the exponent field: all ones for inf and NaN
            worst = max(worst, bits[x] & np.uint32(0x7F800000))
    for y in range(h):
        hr = height[y]
        dr = depth[y]
        mk = mask[y]
        for x in range(w):
            s = hr[x] * levels_per_px
            s = s if s >= zero else zero  # np.maximum(s, 0.0) for finite s
            s = s if s <= top else top
            s = s * (one if mk[x] != 0 else zero)
            dr[x] = np.uint8(np.int32(np.rint(s)))  # 0 .. 255: through int32, which vectorises
    return worst != np.uint32(0x7F800000)


def warm() -> None:
    """Load every kernel (compile it on the first run of an environment, else from numba's cache)
    for the argument types the stage passes, writable and read-only frames and masks, so that no
    frame waits for it."""
    frame = np.zeros((2, 6), np.uint8)
    mask = np.full((2, 2), 255, np.uint8)
    bg = np.zeros((2, 6), np.float32)
    glut = np.zeros(16, np.float32)
    work = np.zeros((2, 2, 2), np.float32)
    div = np.zeros((1, 1), np.float32)
    scratch = np.zeros(12, np.int64)
    ro_frame, ro_mask = frame.copy(), mask.copy()
    ro_frame.setflags(write=False)  # a read-only array is another compiled form
    ro_mask.setflags(write=False)
    for f in (frame, ro_frame):
        for m in (mask, ro_mask):
            gradients_divergence(f, m, bg, glut, work, div, scratch, np.float32(1.0), np.float32(1.0), 2, 0.5)
    for m in (mask, ro_mask):
        depth_image(div, m, np.float32(1.0), work[0], np.zeros((2, 2), np.uint8))
