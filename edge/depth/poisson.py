"""Exact Poisson integration of a gradient field with the Discrete Sine Transform (DST-I).

Grid and boundary (H x W height map ``h``, pixels):

* unknowns are the pixels ``h[1:, 1:]`` ((H-1) x (W-1) values); ``h`` is 0 on row 0, on
  column 0, and on the virtual row H and column W just outside the frame (Dirichlet).
  For a 320 x 240 DIGIT frame the interior is 319 x 239, so the DST-I length 2(n+1) is
  640 and 480: fast FFT sizes (318 x 238 would be 638 = 2*11*29 and 478 = 2*239).
* gradients are forward differences: ``gx[i, j] = h[i, j+1] - h[i, j]`` (along columns),
  ``gy[i, j] = h[i+1, j] - h[i, j]`` (along rows), with the virtual row/column = 0.
* the divergence with backward differences is then exactly the 5-point Laplacian, and the
  DST-I diagonalises it with eigenvalues ``2 cos(pi k/(n+1)) - 2`` per axis, so a height
  map that is 0 on the boundary is recovered from its own discrete gradients to float
  precision.

On a full-resolution grid the backend is ``scipy.fft`` (native DST-I, 1.0 ms for a 319 x 239
float32 solve on one core of the AMD EPYC VM), from the ``paper`` extra: a solver on such a grid
without SciPy raises :class:`~tactile_force.edge.errors.MissingExtraError` when it is made, before
any frame. numpy's real FFT of the odd extension (``backend="numpy"``, only when asked for) is
exact as well and 12x slower (11.7 ms).
On a small grid (both sides at most :data:`MATMUL_MAX_N` unknowns, e.g. the 79 x 59 interior
of an 80 x 60 network-resolution depth grid) the DST-I is applied as two products with
precomputed sine matrices (``backend = "matmul"``): the same transform, exact to float
rounding, and about half the time of two FFT calls at that size, where the calls' fixed
cost dominates.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from ..errors import MissingExtraError

#: Solver array dtypes that are supported.
_DTYPES = (np.float32, np.float64)
#: 'auto' uses the dense sine-matrix DST-I when both interior sides are at most this long.
MATMUL_MAX_N = 128


def _sine_matrix(n: int, dtype) -> np.ndarray:
    """The unnormalised DST-I of length n as a matrix: S[j, k] = 2 sin(pi (j+1)(k+1)/(n+1))
    (symmetric; ``S @ x`` equals scipy's ``dst(x, type=1)``)."""
    k = np.arange(1, n + 1, dtype=np.float64)
    return np.ascontiguousarray((2.0 * np.sin(np.pi * np.outer(k, k) / (n + 1))).astype(dtype))


def _eigenvalues(n: int, dtype) -> np.ndarray:
    k = np.arange(1, n + 1, dtype=np.float64)
    return (2.0 * np.cos(np.pi * k / (n + 1)) - 2.0).astype(dtype)


class _NumpyDST1:
    """Unnormalised DST-I along the last or first axis through numpy's rfft of the odd
    extension ``[0, x, 0, -x reversed]`` (length 2(n+1)); buffers allocated once."""

    def __init__(self, rows: int, cols: int, dtype) -> None:
        self.rows, self.cols = rows, cols
        self.buf_c = np.zeros((rows, 2 * (cols + 1)), dtype=dtype)  # transform along columns axis
        self.buf_r = np.zeros((cols, 2 * (rows + 1)), dtype=dtype)  # transform along rows axis

    @staticmethod
    def _along_last(x: np.ndarray, buf: np.ndarray) -> np.ndarray:
        n = x.shape[-1]
        buf[:, 1:n + 1] = x
        buf[:, n + 2:] = x[:, ::-1]
        buf[:, n + 2:] *= -1
        spec = np.fft.rfft(buf, axis=-1)
        # FFT of the odd extension = -2i * sum_j x_j sin(pi (j+1) k/(n+1)); scipy's DST-I is 2*sum.
        return -spec.imag[:, 1:n + 1]

    def dst2d(self, x: np.ndarray) -> np.ndarray:
        y = self._along_last(x, self.buf_c)
        return self._along_last(y.T, self.buf_r).T


class PoissonSolver:
    """Reusable exact solver for one frame shape.

    ``solve(gx, gy, out=None)``: gx, gy: H x W float gradients (height units per pixel,
    forward differences as in the module doc); returns the H x W height map with the
    Dirichlet boundary above. The eigenvalue table and work arrays are made once here.
    """

    def __init__(self, shape: tuple[int, int], dtype=np.float32, backend: str = "auto") -> None:
        h, w = int(shape[0]), int(shape[1])
        if h < 2 or w < 2:
            raise ValueError(f"PoissonSolver shape {shape}: need at least 2 x 2 pixels")
        self.dtype = np.dtype(dtype)
        if self.dtype.type not in _DTYPES:
            raise ValueError(f"PoissonSolver dtype {dtype}: expected float32 or float64")
        self.shape = (h, w)
        n_r, n_c = h - 1, w - 1
        lam = _eigenvalues(n_r, np.float64)[:, None] + _eigenvalues(n_c, np.float64)[None, :]
        # Inverse of the Laplacian eigenvalues, including the DST-I round-trip normalisation:
        # scipy's unnormalised DST-I applied twice per axis multiplies by 2(n+1).
        norm = (2.0 * (n_r + 1)) * (2.0 * (n_c + 1))
        self._inv_lam = (1.0 / (lam * norm)).astype(self.dtype)
        self._div = np.zeros((n_r, n_c), dtype=self.dtype)
        self.backend = self._pick_backend(backend, max(n_r, n_c))
        if self.backend == "numpy":
            self._np = _NumpyDST1(n_r, n_c, self.dtype)
        if self.backend == "matmul":
            self._s_r = _sine_matrix(n_r, self.dtype)
            self._s_c = _sine_matrix(n_c, self.dtype)
            self._tmp = np.empty((n_r, n_c), dtype=self.dtype)
            self._spec = np.empty((n_r, n_c), dtype=self.dtype)

    @staticmethod
    def _pick_backend(backend: str, longest: int = MATMUL_MAX_N + 1) -> str:
        if backend not in ("auto", "scipy", "numpy", "matmul"):
            raise ValueError(f"PoissonSolver backend {backend!r}: expected 'auto', 'scipy', 'numpy' or 'matmul'")
        if backend == "matmul" or (backend == "auto" and longest <= MATMUL_MAX_N):
            return "matmul"
        if backend in ("auto", "scipy"):
            if importlib.util.find_spec("scipy") is None:
                raise MissingExtraError("scipy", "paper", f"the DST-I Poisson solve on a {longest}-pixel grid "
                                        "(full-resolution depth, the paper's mode)")
            return "scipy"
        return "numpy"

    def _dst2d(self, x: np.ndarray) -> np.ndarray:
        if self.backend == "matmul":  # S_r @ x @ S_c (both symmetric), into reused buffers
            np.matmul(self._s_r, x, out=self._tmp)
            out = self._spec if x is not self._spec else x
            np.matmul(self._tmp, self._s_c, out=out)
            return out
        if self.backend == "scipy":
            import scipy.fft as sfft

            return sfft.dstn(x, type=1, workers=1, overwrite_x=True)
        return self._np.dst2d(x)

    def divergence(self, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
        """Backward-difference divergence on the interior h[1:, 1:]; returns the internal
        (H-1) x (W-1) buffer (overwritten by the next call)."""
        d = self._div
        np.subtract(gx[1:, 1:], gx[1:, :-1], out=d, casting="unsafe")
        d += gy[1:, 1:]
        d -= gy[:-1, 1:]
        return d

    def solve_divergence(self, d: np.ndarray) -> np.ndarray:
        """The interior heights (H-1) x (W-1) whose 5-point Laplacian is ``d`` (the
        :meth:`divergence`, or the same values computed elsewhere; ``d`` may be overwritten):
        DST-I, divide by the eigenvalues, DST-I. Returns an internal buffer (overwritten by the
        next call)."""
        spec = self._dst2d(d)
        spec *= self._inv_lam
        return self._dst2d(spec)

    def solve(self, gx: np.ndarray, gy: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Height map H x W (same units as the gradients times pixels) from gradients."""
        if gx.shape != self.shape or gy.shape != self.shape:
            raise ValueError(f"gradients shapes {gx.shape}, {gy.shape}: expected {self.shape} (rows, cols)")
        interior = self.solve_divergence(self.divergence(gx, gy))
        if out is None:
            out = np.zeros(self.shape, dtype=self.dtype)
        else:
            out[0, :] = 0
            out[:, 0] = 0
        out[1:, 1:] = interior
        return out


def forward_gradients(height: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Discrete forward-difference gradients of an H x W height map with the solver's zero
    boundary (virtual row H and column W = 0): gx along columns, gy along rows."""
    h = np.asarray(height)
    gx = np.empty_like(h)
    gy = np.empty_like(h)
    gx[:, :-1] = h[:, 1:] - h[:, :-1]
    gx[:, -1] = -h[:, -1]
    gy[:-1, :] = h[1:, :] - h[:-1, :]
    gy[-1, :] = -h[-1, :]
    return gx, gy
