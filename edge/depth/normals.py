"""The paper's colour -> surface-normal MLP, evaluated in numpy.

Weights come from a user-given .npz (e.g. ../shared/data/aurova_digit_depth_mlp.npz; it
is not shipped in the package): fc1 (32x5), fc2 (32x32), fc3 (32x32), fc4 (3x32) plus
biases, ReLU after fc1 and fc2 only. Input per pixel: (col/240, row/320, R/255, G/255,
B/255) in RGB order. Output: the normal encoded as (n + 1) / 2 with the digit-depth
labelling convention n = (nx, -ny, nz) (y up); :func:`decode_paper_normals` turns it into
this package's convention (y down, see gradients.py).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..errors import TactileForceError

_LAYERS = (("fc1", (32, 5)), ("fc2", (32, 32)), ("fc3", (32, 32)), ("fc4", (3, 32)))


class MappingError(TactileForceError, ValueError):
    """A colour->normal mapping file is missing, truncated or of the wrong layout."""


def _load_npz(path: str | os.PathLike) -> dict[str, np.ndarray]:
    p = Path(path)
    if not p.is_file():
        raise MappingError(f"{p}: mapping file not found (expected the paper MLP .npz or a calibrate-depth .npz)")
    try:
        with np.load(p, allow_pickle=False) as z:
            return {k: z[k] for k in z.files}
    except Exception as exc:  # zipfile/pickle/ValueError: truncated or not an npz
        raise MappingError(f"{p}: cannot read as .npz ({exc.__class__.__name__}: {exc}); "
                           "file empty or truncated?") from None


def is_paper_mlp(arrays: dict[str, np.ndarray]) -> bool:
    """True when the npz arrays look like the paper MLP (fc1.weight ... or fc1_weight ...)."""
    return any(k in arrays for k in ("fc1.weight", "fc1_weight"))


class PaperMLP:
    """The paper's 5-32-32-32-3 MLP. ``encoded(frame, index)`` -> (N, 3) float32 in the
    paper's (n + 1)/2 encoding for the pixels ``index`` (flat indices into H x W)."""

    def __init__(self, weights: dict[str, np.ndarray], source: str = "<arrays>") -> None:
        self.source = source
        self.w: list[np.ndarray] = []
        self.b: list[np.ndarray] = []
        for name, shape in _LAYERS:
            w = weights.get(f"{name}.weight", weights.get(f"{name}_weight"))
            b = weights.get(f"{name}.bias", weights.get(f"{name}_bias"))
            if w is None or b is None:
                raise MappingError(f"{source}: missing {name} weight/bias; expected fc1..fc4 of a 5-32-32-32-3 MLP")
            if w.shape != shape or b.shape != (shape[0],):
                raise MappingError(f"{source}: {name} weight {w.shape} bias {b.shape}; "
                                   f"expected {shape} and ({shape[0]},)")
            if not (np.all(np.isfinite(w)) and np.all(np.isfinite(b))):
                raise MappingError(f"{source}: {name} holds NaN or inf (corrupted weights)")
            # Stored transposed so a row-major (N, in) batch multiplies without copies.
            self.w.append(np.ascontiguousarray(w.T, dtype=np.float32))
            self.b.append(b.astype(np.float32))
        self._grid: tuple[int, int, int] | None = None
        #: Full-resolution pixels per pixel of the frames given (k for a frame reduced k x k):
        #: the position inputs are the block centres' full-resolution coordinates.
        self.pitch = 1
        # Fast form, same function: fc3 and fc4 have no activation between them, so they fold
        # into one 32 -> 3 layer; fc1's position part (col/240, row/320) is a per-pixel table
        # made once per frame size, its colour part a 3 -> 32 product with 1/255 folded in.
        w1 = self.w[0].astype(np.float64)
        self._w_colour = np.ascontiguousarray((w1[2:][::-1] / 255.0).astype(np.float32))  # BGR rows
        self._w_pos = w1[:2]
        self._w34 = np.ascontiguousarray((self.w[2].astype(np.float64) @ self.w[3]).astype(np.float32))
        self._b34 = (self.b[2].astype(np.float64) @ self.w[3] + self.b[3]).astype(np.float32)
        self._pos: np.ndarray | None = None
        self._work: tuple[np.ndarray, ...] | None = None

    @classmethod
    def load(cls, path: str | os.PathLike) -> PaperMLP:
        arrays = _load_npz(path)
        if not is_paper_mlp(arrays):
            raise MappingError(f"{path}: keys {sorted(arrays)[:6]}...; expected the paper MLP (fc1.weight ...)")
        return cls(arrays, str(path))

    def _coords(self, shape: tuple[int, int]) -> None:
        key = (shape[0], shape[1], self.pitch)
        if self._grid != key:
            h, w = shape
            rows, cols = np.mgrid[0:h, 0:w].astype(np.float64)
            k = self.pitch
            rows, cols = rows * k + (k - 1) / 2.0, cols * k + (k - 1) / 2.0  # block centres (full resolution)
            # The authors normalise by the DIGIT size 240 x 320 whatever the frame.
            xy = np.stack([cols.ravel() / 240.0, rows.ravel() / 320.0], axis=1)
            self._xy = xy.astype(np.float32)
            self._pos = (xy @ self._w_pos + self.b[0]).astype(np.float32)  # (H*W, 32): fc1's position part
            self._grid = key

    def _buffers(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Two (n, 32) and (n, 3) float32 work buffers, grown when needed and reused (fresh
        multi-MB arrays per frame cost page faults: the MLP took twice as long)."""
        if self._work is None or self._work[0].shape[0] < n:
            self._work = (np.empty((n, 32), np.float32), np.empty((n, 3), np.float32))
        return self._work[0][:n], self._work[1][:n]

    def encoded(self, frame: np.ndarray, index: np.ndarray | None = None) -> np.ndarray:
        """frame: H x W x 3 uint8 BGR; index: flat pixel indices (None = all).
        Returns (N, 3) float32 (n + 1)/2 encoded normals, digit-depth convention (a new
        array). Pixels are independent: ``encoded(f, idx) == encoded(f)[idx]``."""
        h, w = frame.shape[:2]
        self._coords((h, w))
        pos = self._pos
        assert pos is not None  # made by _coords
        flat = frame.reshape(-1, 3)
        if index is None:
            bgr, a = flat, pos.copy()
        else:  # np.take gathers faster than fancy indexing (and than take into a buffer)
            bgr, a = np.take(flat, index, axis=0), np.take(pos, index, axis=0)
        b, out = self._buffers(a.shape[0])
        np.matmul(bgr.astype(np.float32), self._w_colour, out=b)
        a += b
        np.maximum(a, 0, out=a)
        np.matmul(a, self.w[1], out=b)
        b += self.b[1]
        np.maximum(b, 0, out=b)
        np.matmul(b, self._w34, out=out)
        out += self._b34
        return out.copy()

    def encoded_reference(self, frame: np.ndarray, index: np.ndarray | None = None) -> np.ndarray:
        """The four layers one by one, as the authors run them (float32): what
        :meth:`encoded` is tested against."""
        h, w = frame.shape[:2]
        self._coords((h, w))
        bgr = frame.reshape(-1, 3)
        xy = self._xy
        if index is not None:
            bgr, xy = bgr[index], xy[index]
        x = np.concatenate([xy, bgr[:, ::-1].astype(np.float32) / 255.0], axis=1)
        a = np.maximum(x @ self.w[0] + self.b[0], 0)
        a = np.maximum(a @ self.w[1] + self.b[1], 0)
        a = a @ self.w[2] + self.b[2]
        return a @ self.w[3] + self.b[3]


def decode_paper_normals(encoded: np.ndarray) -> np.ndarray:
    """(N, 3) paper encoding (n + 1)/2, y up -> (N, 3) unit normals, y down (this package's
    convention). Zero-length vectors become (0, 0, 1)."""
    n = encoded.astype(np.float32, copy=True)
    n *= 2.0
    n -= 1.0
    n[:, 1] *= -1.0
    norm = np.sqrt(np.einsum("ij,ij->i", n, n))
    bad = ~(norm > 1e-6)
    norm[bad] = 1.0
    n /= norm[:, None]
    n[bad] = (0.0, 0.0, 1.0)
    return n
