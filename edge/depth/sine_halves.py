"""The Poisson solve's DST-I on a small grid by its even and odd halves (edge/depth/poisson.py).

The unnormalised DST-I of length n, ``S[j, k] = 2 sin(pi (j+1)(k+1)/(n+1))``, is symmetric and
``S[j, n-1-k] = (-1)^j S[j, k]``. So an output of even index j reads only the folded sums
``u[k] = x[k] + x[n-1-k]`` and one of odd index only the differences ``v[k] = x[k] - x[n-1-k]``:
the dense product ``S @ x`` (n^2 products per column) becomes ``E @ u`` and ``O @ v`` with E
ceil(n/2) and O floor(n/2) square, half the products. For odd n the middle value is its own
partner: ``u[m] = 2 x[m]`` and E's middle column is halved, so the fold is two whole-array
calls on every length.

The 2-D solve keeps its spectrum in split order (even then odd indices, along both axes): the
eigenvalue table is permuted to match once, so nothing is put back in order between the forward
and inverse transforms. The inverse unfolds: with ``P = E^T X_even`` and ``Q = O'^T X_odd``
(O' the odd rows of S over the first ceil(n/2) columns, zero on the middle column),
``y[:ceil(n/2)] = P + Q`` and ``y[n-1-j] = P[j] - Q[j]`` for j < n/2.

The same transform as the dense matrices, to float rounding (tests/edge/depth/test_sine_halves.py);
a 79 x 59 interior (an 80 x 60 depth grid) costs half the multiply-adds of the dense products.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SineHalves", "sine_matrix"]


def sine_matrix(n: int) -> np.ndarray:
    """The unnormalised DST-I of length n as a float64 matrix: S[j, k] = 2 sin(pi (j+1)(k+1)/(n+1))
    (symmetric; ``S @ x`` equals scipy's ``dst(x, type=1)``)."""
    k = np.arange(1, n + 1, dtype=np.float64)
    return 2.0 * np.sin(np.pi * np.outer(k, k) / (n + 1))


class _Axis:
    """The halves of the DST-I of length ``n`` along one axis: ``ne`` = ceil(n/2) even outputs,
    ``m`` = floor(n/2) odd ones; the forward matrices (E with its middle column halved, O) and the
    inverse ones (E^T, O'^T), in ``dtype``."""

    def __init__(self, n: int, dtype: np.dtype) -> None:
        s = sine_matrix(n)
        self.n, self.m, self.ne = n, n // 2, n - n // 2
        ne, m = self.ne, self.m
        e = s[0::2, :ne].copy()  # ne x ne: the even rows over the first ne columns
        if n % 2:
            e[:, m] *= 0.5  # the fold doubles the middle value
        self.fwd_e = np.ascontiguousarray(e.astype(dtype))
        self.fwd_o = np.ascontiguousarray(s[1::2, :m].astype(dtype))  # m x m
        self.inv_e = np.ascontiguousarray(s[0::2, :ne].T.astype(dtype))  # ne x ne: E^T, unhalved
        self.inv_o = np.ascontiguousarray(s[1::2, :ne].T.astype(dtype))  # ne x m: O'^T (middle row 0)

    def order(self) -> np.ndarray:
        """The natural indices in split order: 0, 2, 4, ..., then 1, 3, 5, ..."""
        return np.concatenate([np.arange(0, self.n, 2), np.arange(1, self.n, 2)])


class SineHalves:
    """The 2-D DST-I of (rows x cols) arrays by halves, into buffers allocated once.

    :meth:`forward` takes the natural-order array and leaves the spectrum in split order;
    :meth:`inverse` takes a split-order spectrum and returns the natural-order result (both
    unnormalised, as scipy's ``dstn(type=1)``). :meth:`split` puts a natural-order table (the
    eigenvalues) in split order once.
    """

    def __init__(self, rows: int, cols: int, dtype) -> None:
        self.dtype = np.dtype(dtype)
        self.r, self.c = _Axis(rows, self.dtype), _Axis(cols, self.dtype)
        self._a = np.empty((rows, cols), self.dtype)  # the folded input
        self._b = np.empty((rows, cols), self.dtype)  # after the rows; then the spectrum
        ner, nec = self.r.ne, self.c.ne
        self._pq = np.empty(max(2 * ner * cols, rows * 2 * nec), self.dtype)  # P and Q of one axis
        self._out = np.empty((rows, cols), self.dtype)
        self._ro, self._co = self.r.order(), self.c.order()

    def split(self, table: np.ndarray) -> np.ndarray:
        """``table`` (rows x cols, natural order) in split order along both axes, a new array."""
        return np.ascontiguousarray(table[self._ro][:, self._co])

    def forward(self, x: np.ndarray) -> np.ndarray:
        """The spectrum of ``x`` (rows x cols) in split order: an internal buffer, overwritten by the
        next :meth:`forward`."""
        r, c = self.r, self.c
        a, b = self._a, self._b
        xr = x[::-1]
        np.add(x[:r.ne], xr[:r.ne], out=a[:r.ne])  # rows folded
        np.subtract(x[:r.m], xr[:r.m], out=a[r.ne:])
        np.matmul(r.fwd_e, a[:r.ne], out=b[:r.ne])
        np.matmul(r.fwd_o, a[r.ne:], out=b[r.ne:])
        br = b[:, ::-1]
        np.add(b[:, :c.ne], br[:, :c.ne], out=a[:, :c.ne])  # columns folded
        np.subtract(b[:, :c.m], br[:, :c.m], out=a[:, c.ne:])
        np.matmul(a[:, :c.ne], c.fwd_e.T, out=b[:, :c.ne])
        np.matmul(a[:, c.ne:], c.fwd_o.T, out=b[:, c.ne:])
        return b

    def inverse(self, spec: np.ndarray) -> np.ndarray:
        """The natural-order transform of the split-order ``spec`` (rows x cols): an internal buffer,
        overwritten by the next :meth:`inverse`."""
        r, c = self.r, self.c
        rows, cols = spec.shape
        pq = self._pq[:2 * r.ne * cols].reshape(2 * r.ne, cols)
        p, q = pq[:r.ne], pq[r.ne:]
        np.matmul(r.inv_e, spec[:r.ne], out=p)
        np.matmul(r.inv_o, spec[r.ne:], out=q)
        a = self._a
        np.add(p, q, out=a[:r.ne])  # rows unfolded
        np.subtract(p[:r.m], q[:r.m], out=a[::-1][:r.m])
        pq = self._pq[:rows * 2 * c.ne].reshape(rows, 2 * c.ne)
        p, q = pq[:, :c.ne], pq[:, c.ne:]
        np.matmul(a[:, :c.ne], c.inv_e.T, out=p)
        np.matmul(a[:, c.ne:], c.inv_o.T, out=q)
        out = self._out
        np.add(p, q, out=out[:, :c.ne])  # columns unfolded
        np.subtract(p[:, :c.m], q[:, :c.m], out=out[:, ::-1][:, :c.m])
        return out
