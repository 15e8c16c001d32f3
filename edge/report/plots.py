"""The package's plots, drawn with OpenCV alone (no matplotlib on a robot host).

One small module serves every verb: ``demo`` and ``run`` (force and truth against time),
``bench`` and ``study`` (error against p99 latency with the budget line, Pareto front),
``compress`` (its students' error against p99) and ``calibrate-force`` (raw and calibrated
estimates against true force with the fitted map). Each function writes a PNG and returns
its path; :class:`Canvas` is the axes they share (ticks, tick labels, titles, legend).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["Canvas", "ParetoPoint", "calibration_plot", "error_vs_latency", "force_vs_time", "nice_ticks",
           "pareto_front"]

BLACK, GREY, GRID = (0, 0, 0), (60, 60, 60), (225, 225, 225)
RED, BLUE, GREEN, ORANGE = (40, 40, 220), (200, 110, 30), (60, 160, 60), (0, 140, 255)
_FONT = 0  # cv2.FONT_HERSHEY_SIMPLEX


def nice_ticks(lo: float, hi: float, n: int = 6) -> list[float]:
    """About ``n`` round tick values (1, 2, 2.5 or 5 x 10^k apart) covering [lo, hi]."""
    span = max(hi - lo, 1e-9)
    raw = span / max(n - 1, 1)
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step - 1e-9) * step
    return [round(first + k * step, 10) for k in range(int((hi - first) / step + 1e-9) + 1)]


def _label(v: float) -> str:
    return f"{v:g}" if abs(v) >= 1e-3 or v == 0 else f"{v:.1e}"


class Canvas:
    """Axes on a white image: data ranges ``xlim`` / ``ylim``, round ticks with labels, axis
    titles and a grid; plot with :meth:`line`, :meth:`points`, :meth:`vline`, :meth:`text`
    and :meth:`legend`, then :meth:`save`.

    Parameters
    ----------
    xlim, ylim : (float, float)
        Data ranges of the axes (x to the right, y upwards).
    xlabel, ylabel : str
        Axis titles (the y title is drawn rotated).
    size : (int, int)
        Image width and height in pixels.
    """

    def __init__(self, xlim: tuple[float, float], ylim: tuple[float, float], xlabel: str, ylabel: str,
                 size: tuple[int, int] = (900, 360)) -> None:
        import cv2

        self.cv2 = cv2
        self.w, self.h = size
        self.left, self.right, self.top, self.bottom = 70, 20, 30, 50
        x0, x1 = float(xlim[0]), float(xlim[1])
        y0, y1 = float(ylim[0]), float(ylim[1])
        self.xlim = (x0, x1 if x1 > x0 else x0 + 1e-6)
        self.ylim = (y0, y1 if y1 > y0 else y0 + 1e-6)
        self.img = np.full((self.h, self.w, 3), 255, np.uint8)
        self._legend_x = self.left
        self._axes(xlabel, ylabel)

    def xy(self, x: float, y: float) -> tuple[int, int]:
        """Pixel of data point (x, y)."""
        (x0, x1), (y0, y1) = self.xlim, self.ylim
        return (round(self.left + (x - x0) / (x1 - x0) * (self.w - self.left - self.right)),
                round(self.h - self.bottom - (y - y0) / (y1 - y0) * (self.h - self.top - self.bottom)))

    def _put(self, text: str, org: tuple[int, int], colour=BLACK, scale: float = 0.45) -> None:
        self.cv2.putText(self.img, text, org, _FONT, scale, colour, 1, self.cv2.LINE_AA)

    def _size(self, text: str, scale: float = 0.45) -> tuple[int, int]:
        (tw, th), _ = self.cv2.getTextSize(text, _FONT, scale, 1)
        return tw, th

    def _axes(self, xlabel: str, ylabel: str) -> None:
        cv2, img, (h, w) = self.cv2, self.img, (self.h, self.w)
        for f in nice_ticks(*self.ylim):
            _, y = self.xy(self.xlim[0], f)
            cv2.line(img, (self.left, y), (w - self.right, y), GRID, 1)
            cv2.line(img, (self.left - 5, y), (self.left, y), BLACK, 1)
            tw, th = self._size(_label(f))
            self._put(_label(f), (self.left - 8 - tw, y + th // 2))
        for ti in nice_ticks(*self.xlim):
            x, _ = self.xy(ti, self.ylim[0])
            cv2.line(img, (x, self.top), (x, h - self.bottom), GRID, 1)
            cv2.line(img, (x, h - self.bottom), (x, h - self.bottom + 5), BLACK, 1)
            tw, th = self._size(_label(ti))
            self._put(_label(ti), (x - tw // 2, h - self.bottom + 8 + th))
        cv2.rectangle(img, (self.left, self.top), (w - self.right, h - self.bottom), BLACK, 1)
        tw, _ = self._size(xlabel, 0.5)
        self._put(xlabel, (w // 2 - tw // 2, h - 10), scale=0.5)
        tw, _ = self._size(ylabel, 0.5)
        strip = np.full((20, tw + 4, 3), 255, np.uint8)
        cv2.putText(strip, ylabel, (2, 15), _FONT, 0.5, BLACK, 1, cv2.LINE_AA)
        rot = cv2.rotate(strip, cv2.ROTATE_90_COUNTERCLOCKWISE)[: h - 4]
        y0 = max(0, (h - rot.shape[0]) // 2)
        img[y0:y0 + rot.shape[0], 4:4 + rot.shape[1]] = rot

    def _inside(self, x: float, y: float) -> bool:
        return bool(np.isfinite(x) and np.isfinite(y))

    def line(self, xs: Sequence[float] | np.ndarray, ys: Sequence[float] | np.ndarray, colour=GREY,
             thickness: int = 2) -> None:
        """A polyline through the finite points (x, y)."""
        pts = [self.xy(a, b) for a, b in zip(xs, ys) if self._inside(a, b)]
        if len(pts) > 1:  # drawn on a copy, kept inside the axes only
            layer = self.img.copy()
            self.cv2.polylines(layer, [np.array(pts, np.int32)], False, colour, thickness, self.cv2.LINE_AA)
            box = (slice(self.top + 1, self.h - self.bottom), slice(self.left + 1, self.w - self.right))
            self.img[box] = layer[box]

    def points(self, xs: Sequence[float] | np.ndarray, ys: Sequence[float] | np.ndarray, colour=RED,
               radius: int = 2, filled: bool = True) -> None:
        """A dot at each finite point; ``filled=False`` draws rings."""
        for a, b in zip(xs, ys):
            if self._inside(a, b):
                self.cv2.circle(self.img, self.xy(a, b), radius, colour, -1 if filled else 2, self.cv2.LINE_AA)

    def vline(self, x: float, colour=RED, label: str = "") -> None:
        """A dashed vertical line at data x (e.g. a latency budget), labelled at the top."""
        px, top = self.xy(x, self.ylim[1])
        _, bottom = self.xy(x, self.ylim[0])
        for y in range(top, bottom, 12):
            self.cv2.line(self.img, (px, y), (px, min(y + 6, bottom)), colour, 2)
        if label:
            tw, _ = self._size(label)
            x = px + 4 if px + 4 + tw <= self.w - self.right - 2 else px - 4 - tw
            self._put(label, (x, top + 14), colour)

    def hspan(self, y0: float, y1: float, colour=(230, 245, 230)) -> None:
        """A shaded horizontal band between data y0 and y1 (drawn under what follows)."""
        _, a = self.xy(self.xlim[0], min(max(y1, self.ylim[0]), self.ylim[1]))
        _, b = self.xy(self.xlim[0], min(max(y0, self.ylim[0]), self.ylim[1]))
        band = self.img[a:b, self.left + 1:self.w - self.right]
        band[(band == 255).all(axis=-1)] = colour

    def text(self, x: float, y: float, label: str, colour=BLACK) -> None:
        """A small label just right of data point (x, y)."""
        if self._inside(x, y):
            px, py = self.xy(x, y)
            tw, _ = self._size(label, 0.4)
            px = min(px + 6, self.w - self.right - tw - 2)
            self.cv2.putText(self.img, label, (px, py - 4), _FONT, 0.4, colour, 1, self.cv2.LINE_AA)

    def legend(self, text: str) -> None:
        """A line of legend text above the axes (appended left to right)."""
        self._put(text, (self._legend_x, self.top - 10))
        self._legend_x += self._size(text)[0] + 20

    def save(self, path: str | os.PathLike) -> Path:
        """Write the PNG (parent folders are made)."""
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        if not self.cv2.imwrite(str(p), self.img):
            raise OSError(f"{p}: could not write the plot")
        return p


def _range(*arrays: Sequence[float] | np.ndarray, floor: float | None = None, pad: float = 0.05
           ) -> tuple[float, float]:
    vals = np.concatenate([np.asarray(a, np.float64).reshape(-1) for a in arrays] or [np.zeros(0)])
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return (0.0, 1.0)
    lo, hi = float(vals.min()), float(vals.max())
    if floor is not None:
        lo = min(lo, floor)
    span = hi - lo if hi > lo else max(abs(hi), 1.0)
    return (lo if floor is not None and lo == floor else lo - pad * span, hi + pad * span)


def force_vs_time(t_s: np.ndarray, estimate_n: np.ndarray, truth_n: np.ndarray | None,
                  path: str | os.PathLike, xlabel: str = "time (s)") -> Path:
    """Force against time: the estimate as red dots, the truth (when known) as a grey line.

    Parameters
    ----------
    t_s : ndarray, shape (N,)
        Time of each reading in s (from 0).
    estimate_n : ndarray, shape (N,)
        Estimated force in N (NaN where none, e.g. no contact).
    truth_n : ndarray, shape (N,), optional
        True force in N (NaN where unknown).
    path : path
        The PNG to write.
    xlabel : str
        What ``t_s`` is (default "time (s)"; e.g. a frame index for a replay read unpaced).

    Returns
    -------
    Path
        ``path``.
    """
    t = np.asarray(t_s, np.float64)
    est = np.asarray(estimate_n, np.float64)
    truth = np.full_like(est, np.nan) if truth_n is None else np.asarray(truth_n, np.float64)
    fmax = max(1.0, float(np.nanmax(np.concatenate([est, truth, [1.0]]))))
    t0 = float(t[0]) if t.size else 0.0
    tmax = max(float(t[-1]) if t.size else 1.0, t0 + 1e-6)
    c = Canvas((t0, tmax), (0.0, fmax), xlabel, "normal force (N)")
    c.line(t, truth, GREY, 2)
    c.points(t, est, RED, 2)
    c.legend("grey line: ground truth   red dots: estimate" if np.isfinite(truth).any() else "red dots: estimate")
    return c.save(path)


@dataclass(frozen=True)
class ParetoPoint:
    """One model on an error-vs-latency plot: ``label``, p99 latency (ms), error (e.g. mean
    RE; None when not measured) and whether the error was measured here (False: taken from
    the bundle's manifest, drawn as a ring); ``also_ms``: the same model's p99 measured
    another way (ms; e.g. ``bench``'s back-to-back figure beside the one at the cadence),
    drawn as a grey mark joined to the point, or None."""

    label: str
    p99_ms: float
    error: float | None
    measured: bool = True
    also_ms: float | None = None


def pareto_front(points: Sequence[ParetoPoint]) -> list[int]:
    """Indices of the points no other point beats on both p99 and error (lower is better),
    sorted by p99; points without an error or a finite p99 are never on the front."""
    ok = [i for i, p in enumerate(points)
          if p.error is not None and math.isfinite(p.error) and math.isfinite(p.p99_ms)]
    front = []
    for i in ok:
        a = points[i]
        dominated = any(points[j].p99_ms <= a.p99_ms and points[j].error <= a.error  # type: ignore[operator]
                        and (points[j].p99_ms < a.p99_ms or points[j].error < a.error)  # type: ignore[operator]
                        for j in ok if j != i)
        if not dominated:
            front.append(i)
    return sorted(front, key=lambda i: points[i].p99_ms)


def error_vs_latency(points: Sequence[ParetoPoint], budget_ms: float | None, path: str | os.PathLike,
                     ylabel: str = "mean relative error (RE)", title: str = "", numbered: bool = False,
                     also: str = "measured another way") -> Path:
    """Error against p99 latency, one point per model, the Pareto front joined by a line
    and the latency budget as a dashed vertical line.

    Parameters
    ----------
    points : sequence of ParetoPoint
        The models; those without an error are drawn on the bottom axis as crosses, those
        without a finite p99 are named below the legend.
    budget_ms : float, optional
        The p99 budget in ms (drawn when given).
    path : path
        The PNG to write.
    ylabel, title : str
        Y axis title; a title line above the plot.
    numbered : bool
        Label the points 1, 2, ... (their order in ``points``) instead of by name, for many
        points (the caller lists the numbers, e.g. a table's ``#`` column).
    also : str
        What the points' ``also_ms`` p99 is, for the legend (e.g. ``"back to back"``).

    Returns
    -------
    Path
        ``path``.
    """
    unmeasured = [str(i + 1) if numbered else p.label for i, p in enumerate(points)
                  if not math.isfinite(p.p99_ms)]  # no latency: named, not drawn
    others = [(p.also_ms, p.error) for p in points
              if p.also_ms is not None and math.isfinite(p.also_ms) and p.error is not None and math.isfinite(p.p99_ms)]
    xs = ([p.p99_ms for p in points if math.isfinite(p.p99_ms)] + [x for x, _ in others]
          + ([budget_ms] if budget_ms is not None else []))
    ys = [p.error for p in points if p.error is not None and math.isfinite(p.p99_ms)]
    c = Canvas(_range(xs, floor=0.0), _range(ys, floor=0.0) if ys else (0.0, 1.0), "p99 latency (ms)", ylabel,
               size=(900, 420))
    if budget_ms is not None:
        c.vline(budget_ms, RED)  # named in the legend row: a label in the plot could cover a point's
    front = pareto_front(points)
    if len(front) > 1:
        c.line([points[i].p99_ms for i in front], [points[i].error or 0.0 for i in front], GREEN, 1)
    c.points([points[i].p99_ms for i in front], [points[i].error or 0.0 for i in front], GREEN, 9, filled=False)
    for i, p in enumerate(points):
        label = str(i + 1) if numbered else p.label
        if not math.isfinite(p.p99_ms):
            continue
        if p.error is None:
            px, py = c.xy(p.p99_ms, c.ylim[0])
            c.cv2.drawMarker(c.img, (px, py - 6), GREY, c.cv2.MARKER_TILTED_CROSS, 10, 2)
            c.text(p.p99_ms, c.ylim[0] + 0.03 * (c.ylim[1] - c.ylim[0]), label, GREY)
            continue
        if p.also_ms is not None and math.isfinite(p.also_ms):
            c.line([p.also_ms, p.p99_ms], [p.error, p.error], GREY, 1)
            px, py = c.xy(p.also_ms, p.error)
            c.cv2.drawMarker(c.img, (px, py), GREY, c.cv2.MARKER_DIAMOND, 9, 2)
        c.points([p.p99_ms], [p.error], BLUE, 5, filled=p.measured)
        c.text(p.p99_ms, p.error, label)
    if title:
        c.legend(title)
    legend = "green ring: Pareto front" if front else "no Pareto front (no point with an error and a p99)"
    if budget_ms is not None:
        legend += f"   red dashes: {budget_ms:g} ms budget"
    if any(not p.measured for p in points if p.error is not None):
        legend += "   ring: error from the bundle's manifest"
    if others:
        legend += f"   grey diamond: p99 {also}"
    if any(p.error is None for p in points):
        legend += "   cross: no error"
    c.legend(legend)
    if unmeasured:
        c.legend("not measured: " + ", ".join(unmeasured))
    return c.save(path)


def calibration_plot(truth_n: np.ndarray, raw_n: np.ndarray, calibrated_n: np.ndarray,
                     map_raw_n: np.ndarray, map_force_n: np.ndarray, path: str | os.PathLike) -> Path:
    """Raw and calibrated estimates against the true force, with the fitted map and y = x.

    Parameters
    ----------
    truth_n, raw_n, calibrated_n : ndarray, shape (N,)
        True force, the model's raw estimate and the calibrated estimate of each press (N).
    map_raw_n, map_force_n : ndarray, shape (K,)
        The fitted map as (raw estimate, calibrated force) knots (N), drawn as a line in
        (calibrated force, raw estimate) axes so it overlays the raw points.
    path : path
        The PNG to write.

    Returns
    -------
    Path
        ``path``.
    """
    t = np.asarray(truth_n, np.float64)
    lim = _range(t, raw_n, calibrated_n, floor=0.0)
    c = Canvas(lim, lim, "true force (N)", "estimated force (N)", size=(640, 560))
    c.line(lim, lim, (170, 170, 170), 1)
    c.line(np.asarray(map_force_n, np.float64), np.asarray(map_raw_n, np.float64), ORANGE, 2)
    c.points(t, raw_n, GREY, 4, filled=False)
    c.points(t, calibrated_n, RED, 3)
    c.legend("grey rings: raw   red: calibrated (leave-one-out)   orange: fitted map   grey line: y = x")
    return c.save(path)
