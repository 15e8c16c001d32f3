"""The depth stage: frame + contact mask -> the paper's 8-bit depth image.

Options -> create -> process -> typed result::

    stage = DepthStage(DepthOptions(mapping="calib.npz"))          # exact mode
    res = stage.process(frame, mask)      # frame 320x240x3 uint8 BGR, mask 320x240 uint8/bool
    res.depth                             # 320x240x1 uint8, 0 outside the mask
    res.ok, res.detail                    # False + why, for unusable input (never raises)

Paper-compatible mode reproduces the authors' depth images (their D / Dmod / RGBmod+D
checkpoints were trained on them) and needs ``set_reference(frames)`` first.

Network resolution (``DepthOptions(downscale=k)``, compact depth bundles): colour -> normal
and the exact DST-I solve run on the frame reduced to the network's input, 320/k x 240/k
(80 x 60 for k = 4), and the depth image comes out at that size::

    stage = DepthStage(DepthOptions(mapping="calib.npz", downscale=4))
    res = stage.process(small_frame, small_mask)   # 80x60x3 uint8 BGR, 80x60 mask
    res.depth                                      # 80x60x1 uint8

A full-resolution frame or mask is reduced first (the frame with the bundle's recorded
reduction, edge/gate/reduce.py, the runtime's one implementation; the mask by "any pixel of the
k x k block"), so both give the same depth when the frame was reduced the same way. Heights
stay in full-resolution pixels (see :class:`DepthOptions`, Notes), so ``levels_per_px`` means
the same at every ``downscale``.

With a ``calibrate-depth`` LUT in exact mode at k > 1 (float32, the compact bundles), the gate's
reduced image and uint8 mask take two compiled passes around the DST-I products where the ``fast``
extra's kernels are compiled for this environment (edge/depth/kernels.py, numba; edge/compiled_path.py
loads them from numba's cache when such a stage is built, never compiling there): the same values,
bit for bit, as the numpy path that every other input, and these without the kernels, take.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import numpy as np

from .. import compiled_path
from ..checks import expect
from ..errors import FrameError
from ..frames import FRAME_SHAPE, check_frame, exposure_problem
from .calibration import NormalLUT
from .depth_image import exact_depth_image, paper_depth_image
from .gradients import normals_to_gradients
from .normals import MappingError, PaperMLP, _load_npz, decode_paper_normals, is_paper_mlp
from .options import MODES, DepthOptions, frame_reducer  # noqa: F401 - MODES, frame_reducer: their old home
from .poisson import PoissonSolver


@dataclass(slots=True)
class DepthResult:
    """depth: H x W x 1 uint8 (a new array; H x W is the stage's grid, 320 x 240 or
    320/k x 240/k at ``downscale`` k); ok: False when the input was unusable (depth
    is then all 0); detail: why not ok, or notes; height: H x W float32 internal buffer
    (exact: px of indentation; paper: the authors' distance map, m), overwritten by the
    next call; contact_px: mask pixels; clamped_px: gradient elements that hit a guard."""

    depth: np.ndarray
    ok: bool
    detail: str = ""
    height: np.ndarray | None = None
    contact_px: int = 0
    clamped_px: int = 0


class DepthStage:
    """Reusable depth stage for 320 x 240 frames (or, at ``downscale`` k, frames already
    reduced to 320/k x 240/k); buffers and tables are made once."""

    def __init__(self, options: DepthOptions) -> None:
        expect(options, DepthOptions, "DepthStage.options", "a DepthOptions(mapping=...)")
        self.options = options
        arrays = _load_npz(options.mapping)
        self.mlp: PaperMLP | None = None
        self.lut: NormalLUT | None = None
        k = options.downscale
        h, w = FRAME_SHAPE[0] // k, FRAME_SHAPE[1] // k
        #: (rows, cols, 1) of the depth images this stage makes (the depth grid).
        self.output_shape = (h, w, 1)
        #: (rows, cols, 3) of the reduced frames the stage reads without reducing them.
        self.grid_frame_shape = (h, w, 3)
        if is_paper_mlp(arrays):
            self.mlp = PaperMLP(arrays, str(options.mapping))
            self.mlp.pitch = k
            self.mlp.encoded(np.zeros(self.grid_frame_shape, np.uint8), np.arange(1))  # tables made now
        else:
            self.lut = NormalLUT.from_arrays(arrays, str(options.mapping))
            if self.lut.background.shape != FRAME_SHAPE:
                raise MappingError(f"{options.mapping}: calibrated on {self.lut.background.shape} frames; "
                                   f"the depth stage needs {FRAME_SHAPE} (DIGIT portrait)")
            # Guarded gradients per LUT cell, once: per frame it is a single table lookup.
            gx, gy, _ = normals_to_gradients(self.lut.flat_lut, options.guards)
            # x k: height (full-resolution px) per grid pixel (DepthOptions, Notes)
            self._glut = (np.stack([gx, gy], axis=1) * np.float32(k)).astype(np.float32)
            b = self.lut.bins
            self._cell_weights = np.array([b * b, b, 1], np.float32)
            self._cell_w = self._cell_weights.reshape(1, 3)  # the 1 x 3 matrix cv2.transform applies
            bg = frame_reducer(k, options.reduction)(self.lut.background) if k > 1 else self.lut.background
            self._bg_box = bg.astype(np.float32) - np.float32(self.lut.bins * self.lut.bin_width / 2.0)
        if options.mode == "paper" and self.mlp is None:
            raise MappingError(f"{options.mapping}: paper mode needs the paper MLP .npz, not a calibrate-depth LUT")
        dtype = np.float32 if options.solver_dtype == "float32" else np.float64
        self.solver = PoissonSolver((h, w), dtype)
        self._gx = np.zeros((h, w), dtype=np.float32)
        self._gy = np.zeros((h, w), dtype=np.float32)
        self._height = np.zeros((h, w), dtype=dtype)
        self._depth = np.zeros((h, w, 1), dtype=np.uint8)
        self._full_mask = np.ones((h, w), dtype=bool)
        self._grid_hw = (h, w)
        self._mask_buf = np.empty((h, w), dtype=bool)  # the contact mask as bool, per frame
        self._mask_f = np.empty((h, w), dtype=np.float32)  # and as 0/1 float32 (the LUT path)
        self._below = np.empty((h, w), np.uint8)  # the saturation count's buffers
        self._below_kept = np.empty((h, w), np.uint8)
        self._lo3 = np.zeros(3, np.float64)
        self._hi3 = np.full(3, 254.0, np.float64)
        self._reducer = frame_reducer(k, options.reduction) if k > 1 else None
        self.reference: np.ndarray | None = None
        self._ref_gx: np.ndarray | None = None  # paper mode: mean reference gradients (outside the mask)
        self._ref_gy: np.ndarray | None = None
        rows, cols = np.mgrid[0:h, 0:w]
        self._cell_of = ((rows // 2) * (w // 2) + cols // 2).ravel()  # mapping_step 2: each pixel's 2x2 cell
        #: whether the compiled kernels (edge/depth/kernels.py) apply: a LUT, exact mode at a
        #: downscale k > 1 (the compact depth bundles), float32 DST-I products; else the numpy path
        self._uses_kernels = (self.lut is not None and options.mode == "exact" and k > 1 and dtype is np.float32
                              and self.solver.backend == "matmul")
        #: the compiled kernels where this process has them, else None: the numpy path
        self._kernels: ModuleType | None = None
        if self._uses_kernels:
            assert self.lut is not None  # _uses_kernels says so
            compiled_path.request("depth")  # from numba's cache; never compiled here
            self._kernels = compiled_path.depth_kernels()
            self._bg_rows = np.ascontiguousarray(self._bg_box.reshape(h, w * 3))
            self._glut_flat = np.ascontiguousarray(self._glut.ravel())  # gx, gy interleaved per cell
            self._scratch = np.zeros(4 + 3 * w, np.int64)  # the mask's box, its columns, a row's bins
            self._work = np.zeros((2, h, w), np.float32)  # gx, gy
            self._inv_width = np.float32(1.0 / self.lut.bin_width)
            self._top = np.float32(self.lut.bins - 1)
            self._levels = np.float32(options.levels_per_px)
            self._div = np.zeros((h - 1, w - 1), np.float32)  # what the DST-I products read
            self._depth_rows = self._depth[..., 0]  # h x w view of the depth image
        self._dilate = None
        if options.paper_dilation_px:
            import cv2

            k = 2 * options.paper_dilation_px + 1
            self._dilate = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))

    # ------------------------------------------------------------------ reference
    @property
    def needs_reference(self) -> bool:
        """True in paper mode until :meth:`set_reference` was called."""
        return self.options.mode == "paper" and self.reference is None

    def set_reference(self, frames) -> int:
        """Paper mode: zero-depth reference = mean authors' map of ``frames`` (no-contact
        frames; the authors used the first 50 of a stream). Returns frames used."""
        if self.options.mode != "paper":
            raise ValueError("set_reference: only paper mode uses a zero-depth reference")
        acc = np.zeros(FRAME_SHAPE[:2], dtype=np.float64)
        agx = np.zeros(FRAME_SHAPE[:2], dtype=np.float64)
        agy = np.zeros(FRAME_SHAPE[:2], dtype=np.float64)
        n = 0
        for f in frames:
            f = getattr(f, "frame", f)
            if self._frame_problem(f) is None:
                acc += self._paper_distance(f)
                agx += self._gx
                agy += self._gy
                n += 1
        if n == 0:
            raise ValueError("set_reference: no usable frame (expected 320x240x3 uint8 BGR, not all-dark/white)")
        self.reference = (acc / n).astype(self._height.dtype)
        self._ref_gx = (agx / n).astype(np.float32)
        self._ref_gy = (agy / n).astype(np.float32)
        return n

    # ------------------------------------------------------------------ per frame
    def _frame_problem(self, frame) -> str | None:
        """Why a frame cannot be used (the shared frame contract + exposure), else None."""
        try:
            shape = getattr(frame, "shape", None)
            want = self.grid_frame_shape if shape == self.grid_frame_shape else FRAME_SHAPE
            check_frame(frame, name="frame", shape=want)
        except FrameError as exc:
            if self.options.downscale > 1:
                return f"{exc} (or {self.grid_frame_shape} already reduced to the depth grid)"
            return str(exc)
        return exposure_problem(frame)

    def _grid_frame(self, frame: np.ndarray) -> np.ndarray:
        """The frame on the depth grid: unchanged at downscale 1 or when already reduced."""
        if self._reducer is None or frame.shape == self.grid_frame_shape:
            return frame
        return self._reducer(frame)

    def _mask(self, mask) -> tuple[np.ndarray | None, str]:
        if mask is None:
            return self._full_mask, ""
        if type(mask) is np.ndarray and mask.dtype == np.uint8 and mask.shape == self._grid_hw:
            return np.greater(mask, 0, out=self._mask_buf), ""  # the gate's reduced mask: the usual case
        m = np.asarray(mask)
        if m.ndim == 3 and m.shape[2] == 1:
            m = m[..., 0]
        grid = self.output_shape[:2]
        if m.shape != FRAME_SHAPE[:2] and m.shape != grid:
            also = f" or {grid} (the depth grid)" if grid != FRAME_SHAPE[:2] else ""
            return None, f"mask: shape {m.shape}; expected {FRAME_SHAPE[:2]}{also} uint8 0/255 or bool"
        if np.issubdtype(m.dtype, np.floating) and not np.all(np.isfinite(m)):
            return None, "mask: holds NaN/inf; expected uint8 0/255 or bool"
        if m.dtype != bool:
            m = m > 0
        if m.shape != grid:  # full-resolution mask on a reduced grid: a grid pixel is in when any of its block is
            k = self.options.downscale
            m = np.asarray(m.reshape(grid[0], k, grid[1], k).any(axis=(1, 3)))
        return m, ""

    def _saturated_px(self, frame: np.ndarray, m: np.ndarray, contact_px: int) -> int:
        """Mask pixels with a channel at 255 (SIMD passes instead of a gather of the mask; none
        to count when no value of the frame is 255)."""
        import cv2

        if frame.flags.c_contiguous and cv2.minMaxLoc(frame.reshape(frame.shape[0], -1))[1] < 255:
            return 0
        if frame.shape[:2] == self._grid_hw:
            below, kept = self._below, self._below_kept
        else:
            below, kept = np.empty(frame.shape[:2], np.uint8), np.empty(frame.shape[:2], np.uint8)
        cv2.inRange(frame, self._lo3, self._hi3, dst=below)  # 255 where no channel is at 255
        cv2.bitwise_and(below, np.ascontiguousarray(m).view(np.uint8), dst=kept)  # m: 0/1 -> 0/1 kept
        return contact_px - cv2.countNonZero(kept)

    def _fail(self, detail: str, contact_px: int = 0) -> DepthResult:
        return DepthResult(depth=np.zeros_like(self._depth), ok=False, detail=detail, contact_px=contact_px)

    def process(self, frame: np.ndarray, mask: np.ndarray | None, *, checked: bool = False) -> DepthResult:
        """Depth image of one frame.

        Parameters
        ----------
        frame
            320x240x3 uint8 BGR; at ``downscale`` k also the frame already reduced to the
            depth grid, (320/k)x(240/k)x3 (a full frame is reduced with ``options.reduction``).
        mask
            Contact mask, 320x240 or (at k > 1) the grid's (320/k)x(240/k), uint8 0/255 or
            bool; None = the whole frame.
        checked
            True when the caller has already checked this very array: a C-contiguous
            (320/k)x(240/k)x3 uint8 image on the depth grid that passed
            :func:`~tactile_force.edge.frames.exposure_problem` (``ForceRuntime`` does, on the
            gate's reduced image); the frame checks are then not repeated.

        Returns
        -------
        DepthResult
            ``depth`` of shape :attr:`output_shape`. Never raises on bad content: ok=False
            with an all-zero depth and the reason in ``detail``.
        """
        try:
            if not (checked and type(frame) is np.ndarray and frame.shape == self.grid_frame_shape
                    and frame.dtype == np.uint8 and frame.flags.c_contiguous):
                problem = self._frame_problem(frame)
                if problem is not None:
                    return self._fail(f"invalid input: {problem}")
            frame = self._grid_frame(frame)
            if (self._kernels is not None and type(mask) is np.ndarray and mask.dtype == np.uint8
                    and mask.shape == self._grid_hw and mask.flags.c_contiguous
                    and frame.shape == self.grid_frame_shape and frame.flags.c_contiguous):
                return self._process_kernels(frame, mask)  # the gate's reduced image and mask
            m, why = self._mask(mask)
            if m is None:
                return self._fail(f"invalid input: {why}")
            import cv2

            contact_px = cv2.countNonZero(np.ascontiguousarray(m).view(np.uint8))
            if contact_px == 0:
                return self._fail("empty mask: no contact to reconstruct")
            sat = self._saturated_px(frame, m, contact_px)
            if sat > self.options.saturated_fraction * contact_px:
                return self._fail(f"saturated: {sat}/{contact_px} contact pixels at 255", contact_px)
            if self.options.mode == "paper":
                return self._process_paper(frame, m, contact_px)
            return self._process_exact(frame, m, contact_px)
        except Exception as exc:  # last line of defence: the runtime loop must survive
            return self._fail(f"depth stage error: {exc.__class__.__name__}: {exc}")

    def _process_kernels(self, frame: np.ndarray, mask: np.ndarray) -> DepthResult:
        """Exact mode with the LUT on the depth grid in two compiled passes around the DST-I
        products: the same values as the numpy path (mask counts and saturation,
        :meth:`_lut_gradients_in_box`, :meth:`_integrate`), bit for bit. ``frame``: C-contiguous
        grid image, ``mask``: C-contiguous grid uint8 mask."""
        assert self.lut is not None and self._kernels is not None
        kernels = self._kernels
        h, w = self._grid_hw
        rows = frame.reshape(h, w * 3)
        contact_px, sat = kernels.gradients_divergence(rows, mask, self._bg_rows, self._glut_flat, self._work,
                                                     self._div, self._scratch, self._inv_width, self._top,
                                                     self.lut.bins, self.options.saturated_fraction)
        if contact_px == 0:
            return self._fail("empty mask: no contact to reconstruct")
        if sat > self.options.saturated_fraction * contact_px:
            return self._fail(f"saturated: {sat}/{contact_px} contact pixels at 255", contact_px)
        interior = self.solver.solve_divergence(self._div)
        if not kernels.depth_image(interior, mask, self._levels, self._height, self._depth_rows):
            return self._fail("non-finite height after integration", contact_px)  # cannot happen: guarded
        return DepthResult(self._depth.copy(), True, "", self._height, contact_px, 0)

    def _process_exact(self, frame: np.ndarray, m: np.ndarray, contact_px: int) -> DepthResult:
        gx, gy = self._gx, self._gy
        gx.fill(0.0)
        gy.fill(0.0)
        clamped = 0
        if self.lut is not None and self.options.mapping_step == 1:
            mf = self._mask_f  # the mask as 0/1 float32: products without a cast per element
            np.copyto(mf, m)
            self._lut_gradients_in_box(frame, m, mf)  # no pixel index needed: slices of the mask's box
            return self._integrate(mf, contact_px, 0)
        idx = np.flatnonzero(m)
        where = idx
        if self.options.mapping_step == 2:  # evaluate at the even row/column pixel of each 2x2 cell
            where, back = self._cell_anchors(m, idx)
        if self.lut is not None:
            g = self._glut[self.lut.index(frame, where)]
            vx, vy = g[:, 0], g[:, 1]
        else:
            assert self.mlp is not None  # a stage has a LUT or the MLP
            n = decode_paper_normals(self.mlp.encoded(frame, where))
            vx, vy, clamped = normals_to_gradients(n, self.options.guards)
            if self.options.downscale > 1:  # height (full-resolution px) per grid pixel
                vx *= self.options.downscale
                vy *= self.options.downscale
        if where is not idx:
            vx, vy = vx[back], vy[back]
        gx.ravel()[idx] = vx
        gy.ravel()[idx] = vy
        return self._integrate(m, contact_px, clamped)

    def _integrate(self, m: np.ndarray, contact_px: int, clamped: int) -> DepthResult:
        """Gradients in ``_gx`` / ``_gy`` -> height (Poisson solve) -> the depth image; ``m``:
        the mask, bool or 0/1 float32."""
        gx, gy = self._gx, self._gy
        if self.options.downscale > 1:
            _midpoint_slopes(gx, gy)
        h = self.solver.solve(gx, gy, out=self._height)
        if not np.isfinite(h).all():  # cannot happen with guarded gradients; kept as a guard
            return self._fail("non-finite height after integration", contact_px)
        exact_depth_image(h, m, self.options.levels_per_px, self._depth)
        detail = f"{clamped} gradient values clamped" if clamped else ""
        return DepthResult(self._depth.copy(), True, detail, h, contact_px, clamped)

    def _cell_anchors(self, m: np.ndarray, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """mapping_step 2: flat indices of the even row/column pixel of every 2x2 cell that
        holds a mask pixel, and for each mask pixel (in flat order) its cell's position in
        that list."""
        h, w = m.shape
        u = np.ascontiguousarray(m).view(np.uint8)
        cells = (u[0::2, 0::2] | u[1::2, 0::2]) | (u[0::2, 1::2] | u[1::2, 1::2])  # (h/2, w/2): any in the cell
        flat_cells = np.flatnonzero(cells)
        rows, cols = np.divmod(flat_cells, w // 2)
        anchors = (2 * rows) * w + 2 * cols
        pos = np.zeros(cells.size, np.intp)
        pos[flat_cells] = np.arange(flat_cells.size)
        back = pos[self._cell_of[idx]]
        return anchors, back

    def _lut_gradients_in_box(self, frame: np.ndarray, m: np.ndarray, mf: np.ndarray) -> None:
        """LUT gradients of the mask pixels into ``_gx`` / ``_gy`` (zero elsewhere), computed on
        the mask's bounding box with slices instead of gathering each pixel: the same cell
        index arithmetic as ``NormalLUT.index``, so the same values. ``m``: the mask (bool),
        ``mf``: the same as 0/1 float32."""
        import cv2

        assert self.lut is not None
        x, y, w, h = cv2.boundingRect(np.ascontiguousarray(m).view(np.uint8))
        box = (slice(y, y + h), slice(x, x + w))
        q = np.subtract(frame[box], self._bg_box[box], dtype=np.float32)
        q *= 1.0 / self.lut.bin_width
        np.maximum(q, 0, out=q)  # clip to [0, bins - 1] (two ufuncs: np.clip's wrapper costs more here)
        np.minimum(q, self.lut.bins - 1, out=q)
        np.floor(q, out=q)  # q >= 0: floor == the integer truncation of NormalLUT.index
        # (q0 * b + q1) * b + q2 as q0 b^2 + q1 b + q2 in one pass (cv2.transform; a matrix
        # product per row costs more): whole numbers below 2^24, exact in float32 in any order
        cells = cv2.transform(q, self._cell_w).astype(np.intp)
        g = np.take(self._glut, cells.reshape(h, w), axis=0)  # (h, w, 2)
        inside = mf[box]  # x 1.0 / x 0.0: what the bool mask's product gives, bit for bit
        np.multiply(g[..., 0], inside, out=self._gx[box])
        np.multiply(g[..., 1], inside, out=self._gy[box])

    def _paper_distance(self, frame: np.ndarray, index: np.ndarray | None = None) -> np.ndarray:
        """The authors' integrated map (metres; lower = pressed toward the camera). index:
        flat pixels where the MLP runs (None: every pixel); elsewhere the gradients are the
        reference frames' mean."""
        h, w = FRAME_SHAPE[:2]
        assert self.mlp is not None  # paper mode needs the MLP (checked at construction)
        o = self.mlp.encoded(frame, index)
        nz = np.maximum(o[:, 2], 0.1 / 255.0)  # their EPS = 0.1 on outputs scaled x255
        vx = np.divide(o[:, 0], nz)
        vx *= self.options.gel_width_m / w
        vy = np.divide(o[:, 1], nz)
        vy *= -self.options.gel_height_m / h
        for v in (vx, vy):
            v[~np.isfinite(v)] = 0.0
        gx, gy = self._gx, self._gy
        if index is None:
            gx.ravel()[:] = vx
            gy.ravel()[:] = vy
        else:
            gx[...] = self._ref_gx
            gy[...] = self._ref_gy
            gx.ravel()[index] = vx
            gy.ravel()[index] = vy
        return self.solver.solve(gx, gy, out=self._height)

    def paper_index(self, m: np.ndarray) -> np.ndarray | None:
        """Flat pixels where paper mode runs the MLP: the mask dilated by
        ``paper_dilation_px`` (None: every pixel)."""
        if self._dilate is None:
            return None
        import cv2

        return np.flatnonzero(cv2.dilate(m.view(np.uint8), self._dilate))

    def _process_paper(self, frame: np.ndarray, m: np.ndarray, contact_px: int) -> DepthResult:
        if self.reference is None:
            return self._fail("paper mode: no zero-depth reference; call set_reference(frames) first", contact_px)
        d = self._paper_distance(frame, self.paper_index(m))
        if not np.isfinite(d).all():
            return self._fail("non-finite depth after integration", contact_px)
        paper_depth_image(d, self.reference, m, self.options.paper_scale, self._depth)
        return DepthResult(self._depth.copy(), True, "", d, contact_px, 0)


def _midpoint_slopes(gx: np.ndarray, gy: np.ndarray) -> None:
    """In place: each forward difference takes the mean slope of its two end pixels (the
    pixel beyond the last row / column is flat), ``g[:, j] = (g[:, j] + g[:, j+1]) / 2``
    (DepthOptions, Notes: network resolution)."""
    # (a + b) * 0.5 == 0.5 * a + 0.5 * b in binary floating point (halving is exact), so these
    # four in-place ufuncs give what a 1 x 2 correlation gives, in less time on a 80 x 60 grid.
    gx[:, :-1] += gx[:, 1:]
    gy[:-1, :] += gy[1:, :]
    gx *= 0.5
    gy *= 0.5
