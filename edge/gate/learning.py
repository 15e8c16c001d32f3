"""The contact gate's background learning (edge/gate/contact_gate.py, ``ContactGate``):
:class:`BackgroundLearner` averages no-contact frames into a background (the first
``background_frames`` live frames, or the frames given to ``capture_background``),
:func:`refresh` lets it follow slow LED drift on frames without contact, and
:class:`RelearnPolicy` holds the mismatch state (why the frame no longer fits the background,
and of which kind) and decides when a mismatched background is re-learnt from the live frame.

A mismatch clears as soon as a frame fits again (:meth:`RelearnPolicy.clear`). Otherwise the
background is re-learnt once ``relearn_frames`` frames in a row were stable (mean thumbnail
change under ``stable_level`` grey levels) with no contact-like blob: after a brightness step
(``photometric``) nothing left once compensated; after a motion (``motion``) always; after a
global change the change must reach at least three of the four borders (a press does not).
The gate does the re-learning itself (:meth:`ContactGate.capture_background` of the frame)
when :meth:`RelearnPolicy.due` says so.
"""

from __future__ import annotations

import logging

import cv2
import numpy as np

from .checks import Reference, borders_changed
from .options import GateOptions

#: the gate's messages keep the gate's logger name
_log = logging.getLogger(f"{__package__}.contact_gate")  # the gate's own logger


class RelearnPolicy:
    """Mismatch state and re-learning decision for one gate.

    Parameters
    ----------
    options : GateOptions
        The gate's options (read at each call: ``relearn_frames``, ``stable_level``,
        ``off_area_frac``).

    Attributes
    ----------
    reason : str
        Why the frame does not fit the background ("" = it fits).
    kind : str
        ``photometric``, ``motion``, ``global`` ("" without a mismatch).
    stable : int
        Stable, blob-free frames counted in a row during the mismatch.
    """

    __slots__ = ("options", "reason", "kind", "stable", "_prev")

    def __init__(self, options: GateOptions) -> None:
        self.options = options
        self.reason = ""
        self.kind = ""
        self.stable = 0
        self._prev: np.ndarray | None = None

    def enter(self, reason: str, kind: str) -> None:
        """Enter (or stay in) a mismatch; the first one logs a warning and restarts the count."""
        if not self.reason:
            _log.warning("contact gate: background mismatch: %s; readings are background_mismatch (force NaN) "
                         "until a frame fits again or the background is re-learnt after %d stable frames",
                         reason, self.options.relearn_frames)
            self.stable = 0
            self._prev = None
        self.reason, self.kind = reason, kind

    def clear(self) -> None:
        """The frame fits the background again (or a new background was set): no mismatch."""
        if self.reason:
            _log.info("contact gate: the frame fits the background again; mismatch cleared")
        self.reason = self.kind = ""
        self.stable = 0
        self._prev = None

    def due(self, thumb: np.ndarray, frac: float, kind: str, inliers: np.ndarray) -> bool:
        """Count this mismatched frame; True when the background is to be re-learnt from it now.

        Parameters
        ----------
        thumb : np.ndarray
            The frame's thumbnail (rows x cols x 3 uint8).
        frac : float
            The changed area after compensation, a fraction of the frame.
        kind : str
            The mismatch's kind (``photometric``, ``motion`` or ``global``).
        inliers : np.ndarray
            rows x cols uint8, non-zero where a thumbnail cell fits the background.

        Returns
        -------
        bool
            ``relearn_frames`` (> 0) stable, blob-free frames in a row have been seen.
        """
        o = self.options
        t = thumb.astype(np.float32)
        stable = self._prev is not None and float(np.mean(np.abs(t - self._prev))) < o.stable_level
        self._prev = t
        # No contact-like blob: after a brightness step nothing is left once compensated; for
        # a global change (another unit, moved gel) the change reaches every border (a press
        # does not) or is a pure shift/rotation.
        if kind == "photometric":
            blob_free = frac < o.off_area_frac
        else:
            blob_free = kind == "motion" or borders_changed(inliers) >= 3
        self.stable = self.stable + 1 if (stable and blob_free) else 0
        return bool(o.relearn_frames and self.stable >= o.relearn_frames)


class BackgroundLearner:
    """No-contact frames averaged into a background: each frame's working image (blurred,
    at the working resolution), its thumbnail and its pixel-noise level, kept as float32
    copies until :meth:`mean`."""

    __slots__ = ("_work", "_thumbs", "_noise")

    def __init__(self) -> None:
        self._work: list[np.ndarray] = []
        self._thumbs: list[np.ndarray] = []
        self._noise: list[float] = []

    def add(self, work: np.ndarray, thumb: np.ndarray, noise: float) -> int:
        """Keep one frame (h x w x 3 and rows x cols x 3 uint8, noise in grey levels); returns
        how many are kept."""
        self._work.append(work.astype(np.float32))
        self._thumbs.append(thumb.astype(np.float32))
        self._noise.append(noise)
        return len(self._work)

    def mean(self) -> tuple[np.ndarray, np.ndarray, float]:
        """(background h x w x 3 float32, thumbnail rows x cols x 3 float32, noise level): the
        means over the kept frames (at least one)."""
        return (np.asarray(np.mean(self._work, axis=0, dtype=np.float32)),
                np.asarray(np.mean(self._thumbs, axis=0, dtype=np.float32)), float(np.mean(self._noise)))

    def clear(self) -> None:
        """Forget the kept frames."""
        self._work.clear()
        self._thumbs.clear()
        self._noise.clear()


def refresh(bg: np.ndarray, bg_thumb: np.ndarray, work: np.ndarray, thumb: np.ndarray, rate: float,
            ref: Reference) -> None:
    """Blend a no-contact frame into the background in place (slow LED drift): ``bg`` (h x w x
    3 float32) += ``rate`` x (``work`` - ``bg``), the same for the thumbnails; the reference's
    derived values are then made again when next needed.

    Parameters
    ----------
    bg, bg_thumb : np.ndarray
        The background and its thumbnail (float32, updated in place).
    work, thumb : np.ndarray
        The frame's working image and thumbnail (uint8, same shapes).
    rate : float
        Weight of the frame, 0 < rate < 1 (``GateOptions.refresh_rate``).
    ref : Reference
        The background's reference (edge/gate/checks.py), told that it changed.
    """
    cv2.accumulateWeighted(work, bg, rate)
    cv2.accumulateWeighted(thumb, bg_thumb, rate)
    ref.refreshed()
