"""Measuring a bundle's data statistics from the frames its model was trained or calibrated on
(the record is :class:`tactile_force.edge.bundle.data_stats.DataStats`; the contact gate and
OpenCV are imported here, never with a manifest)."""

from __future__ import annotations

import logging
from collections.abc import Iterable

import numpy as np

from ..bundle.data_stats import DataStats
from ..gate import ContactGate, GateOptions

_log = logging.getLogger(__name__)


def compute_data_stats(frames_bgr: Iterable[np.ndarray], background: np.ndarray | Iterable[np.ndarray] | None,
                       source: str = "", gate_options: GateOptions | None = None,
                       lo_pct: float = 0.5, hi_pct: float = 99.5) -> DataStats:
    """Statistics of ``frames_bgr`` (each HxWx3 uint8 BGR, e.g. a bundle's calibration or
    training frames) seen through the contact gate with ``background`` (one no-contact frame
    or several) as its background. ``background`` None: the colour ranges only
    (``contact_measured`` False; the thumbnails do not depend on the background).

    The gate runs with ``gate_options`` (default :class:`GateOptions`) with its judging off
    and its background frozen, so every frame is measured against the same background.
    Returns a :class:`DataStats` for the manifest's ``data_stats``.
    """
    import dataclasses



    opts = dataclasses.replace(gate_options or GateOptions(), trust=False, refresh_rate=0.0)
    gate = ContactGate(opts)
    measured = background is not None
    if background is not None:
        bgs = [background] if isinstance(background, np.ndarray) and background.ndim == 3 else list(background)
        gate.capture_background(bgs)
    thumbs, areas, deforms = [], [], []
    for frame in frames_bgr:
        if not gate.background_ready:  # no background: any frame will do, only the thumbnails are kept
            gate.capture_background([frame])
        r = gate.update(frame)
        assert r.thumb is not None
        thumbs.append(r.thumb.astype(np.float32))
        if r.contact and measured:
            areas.append(r.area_frac)
            deforms.append(r.deformation)
    if not thumbs:
        raise ValueError("compute_data_stats: no frames given; expected the frames the bundle was trained or "
                         "calibrated on")
    t = np.stack(thumbs)
    rows, cols = t.shape[1:3]
    means = t.reshape(len(t), -1, 3).mean(axis=1)
    return DataStats(
        frames=len(t), contact_frames=len(areas), thumb_rows=int(rows), thumb_cols=int(cols),
        cell_lo=[round(float(v), 2) for v in np.percentile(t, lo_pct, axis=0).ravel()],
        cell_hi=[round(float(v), 2) for v in np.percentile(t, hi_pct, axis=0).ravel()],
        channel_mean=[round(float(v), 3) for v in means.mean(axis=0)],
        channel_std=[round(float(v), 3) for v in means.std(axis=0)],
        contact_area_frac_max=round(float(max(areas)), 5) if areas else None,
        deformation_max=round(float(max(deforms)), 3) if deforms else None,
        contact_measured=measured,
        background_thumb=_background_thumb(bgs[0], int(rows), int(cols)) if background is not None else [],
        source=source or f"{len(t)} frames",
    )


def _background_thumb(frame: np.ndarray, rows: int, cols: int) -> list[float]:
    from ..bundle.force_calibration import look

    t = look(np.asarray(frame))
    return [round(float(v), 2) for v in t.ravel()] if t.shape[:2] == (rows, cols) else []


def frames_data_stats(frames_bgr: Iterable[np.ndarray], background: object, source: str,
                      tool: str) -> DataStats:
    """:func:`compute_data_stats` for a tool that writes a bundle (export, quantize, compress).

    background: None, a no-contact frame (HxWx3 uint8 BGR) or the path of one (image file or
    folder of them); without one only the colour ranges are recorded and a warning says the
    contact-size check is off. Raises :class:`~.errors.SourceError` for an unreadable background.
    """
    import os

    if isinstance(background, (str, os.PathLike)):
        from ..sources import load_background  # OpenCV: imported only here

        background = load_background(background)
    if background is None:
        _log.warning("%s: no no-contact background given: data_stats record the frames' colours (the "
                     "out-of-distribution check) but not their contact sizes (the contact-size check is off); "
                     "pass --background NO_CONTACT.png to record both", tool)
    return compute_data_stats(frames_bgr, background, source=source)  # type: ignore[arg-type]


def no_frames_warning(tool: str, why: str) -> str:
    """The ``data_stats_missing`` text for a bundle written without frames, also logged as a warning."""
    text = (f"{tool} saw no {why}: no data statistics, so the runtime's out-of-distribution and contact-size "
            "checks are OFF for this bundle")
    _log.warning("%s", text)
    return text
