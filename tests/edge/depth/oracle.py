"""The numpy chain the depth stage's compiled kernels replace (edge/depth/kernels.py): exact mode with
a calibrate-depth LUT at a downscale k > 1, on the gate's reduced image and uint8 mask, as the stage
computed it before the kernels. The oracle they are compared against, bit for bit
(tests/edge/depth/test_depth_kernels.py). Not a runtime path."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from tactile_force.edge.depth import DepthStage


@dataclass
class OracleDepth:
    """What the stage returns: ok, detail, contact pixels, depth (h x w x 1 uint8), height (h x w float32)."""

    ok: bool
    detail: str
    contact_px: int
    depth: np.ndarray
    height: np.ndarray | None


def oracle_depth(stage: DepthStage, frame: np.ndarray, mask: np.ndarray) -> OracleDepth:
    """``frame``: the reduced h x w x 3 uint8 image, ``mask`` the reduced h x w uint8 mask; the
    stage's tables (its LUT gradients, reduced background, sine matrices, eigenvalues) are read,
    never its per-frame buffers."""
    assert stage.lut is not None and stage.options.downscale > 1
    h, w = mask.shape
    zeros = np.zeros((h, w, 1), np.uint8)
    m = mask > 0
    contact_px = cv2.countNonZero(m.view(np.uint8))
    if contact_px == 0:
        return OracleDepth(False, "empty mask: no contact to reconstruct", 0, zeros, None)
    below = cv2.inRange(frame, np.zeros(3), np.full(3, 254.0))
    sat = contact_px - cv2.countNonZero(cv2.bitwise_and(below, m.view(np.uint8)))
    if sat > stage.options.saturated_fraction * contact_px:
        return OracleDepth(False, f"saturated: {sat}/{contact_px} contact pixels at 255", contact_px, zeros, None)
    # the LUT gradients on the mask's bounding box (stage._lut_gradients_in_box before the kernels)
    gx = np.zeros((h, w), np.float32)
    gy = np.zeros((h, w), np.float32)
    mf = np.zeros((h, w), np.float32)
    np.copyto(mf, m)
    x, y, bw, bh = cv2.boundingRect(m.view(np.uint8))
    box = (slice(y, y + bh), slice(x, x + bw))
    q = np.subtract(frame[box], stage._bg_box[box], dtype=np.float32)
    q *= 1.0 / stage.lut.bin_width
    np.maximum(q, 0, out=q)
    np.minimum(q, stage.lut.bins - 1, out=q)
    np.floor(q, out=q)
    cells = cv2.transform(q, stage._cell_w).astype(np.intp)
    g = np.take(stage._glut, cells.reshape(bh, bw), axis=0)
    np.multiply(g[..., 0], mf[box], out=gx[box])
    np.multiply(g[..., 1], mf[box], out=gy[box])
    # the mean slope of each forward difference (stage._midpoint_slopes)
    gx[:, :-1] += gx[:, 1:]
    gy[:-1, :] += gy[1:, :]
    gx *= 0.5
    gy *= 0.5
    # the divergence and the DST-I solve (PoissonSolver, backend 'matmul')
    solver = stage.solver
    d = np.zeros((h - 1, w - 1), np.float32)
    np.subtract(gx[1:, 1:], gx[1:, :-1], out=d, casting="unsafe")
    d += gy[1:, 1:]
    d -= gy[:-1, 1:]
    tmp = np.empty_like(d)
    spec = np.empty_like(d)
    np.matmul(solver._s_r, d, out=tmp)
    np.matmul(tmp, solver._s_c, out=spec)
    spec *= solver._inv_lam
    np.matmul(solver._s_r, spec, out=tmp)
    np.matmul(tmp, solver._s_c, out=spec)
    height = np.zeros((h, w), np.float32)
    height[1:, 1:] = spec
    if not np.isfinite(height).all():
        return OracleDepth(False, "non-finite height after integration", contact_px, zeros, height)
    # the depth image (depth_image.exact_depth_image)
    scaled = np.multiply(height, stage.options.levels_per_px, dtype=np.float32)
    np.maximum(scaled, 0.0, out=scaled)
    np.minimum(scaled, 255.0, out=scaled)
    np.multiply(scaled, mf, out=scaled)
    np.rint(scaled, out=scaled)
    depth = np.zeros((h, w, 1), np.uint8)
    depth[..., 0] = scaled
    return OracleDepth(True, "", contact_px, depth, height)
