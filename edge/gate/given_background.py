"""Is a background given to the runtime really a no-contact image?

A background that holds a press makes the gate read that press as "no contact": a grasp at
12 N would read 0 N ``no_contact``. A single frame cannot tell a press from a sensor's own
structure, so the given background is compared with a no-contact image of the same sensor
that the bundle carries:

- the force calibration's sensor fingerprint (``force_calibration.sensor``, written by
  ``calibrate-force``: the sensor's no-contact colours on a 20 x 15 grid), else
- the data statistics' background (``data_stats.background_thumb``, written by export,
  quantize and compress when they were given ``--background``).

After a per-channel gain and offset (LED drift), the cells that do not fit are found; when
most of the image fits (the same sensor) and the misfit forms one compact blob away from the
frame's border, the background differs from the sensor's no-contact image like a press does.
With no reference in the bundle the check cannot run and says so once.

``calibrate-force --background`` is checked the same way before it becomes the sensor's
recorded no-contact image (:func:`given_background_press`): against the source bundle's
reference, else against the lightest press (the image that calibration would record without
``--background``, with the rule the runtime applies to such a reference).
"""

from __future__ import annotations

import numpy as np

#: Share of the grid that must fit for the image to be this sensor at all (else: another sensor).
MIN_SAME_SENSOR_FIT = 0.3
#: Smallest blob of misfit cells (share of the grid) that reads as a press (~ a 5 mm contact on a DIGIT).
MIN_PRESS_CELLS = 0.02
#: The same against a reference taken from the lightest calibration press (it holds that press).
FROM_PRESS_CELLS = 0.10


def fingerprint_reference(fp, what: str = "") -> tuple[np.ndarray, str, float]:
    """(thumbnail rows x cols x 3, what it is, smallest press blob as a share of the grid) of a
    :class:`~.force_calibration.SensorFingerprint` with a thumbnail. ``what``: how messages
    name it (default: the image of the sensor the force calibration was fitted on)."""
    return (np.asarray(fp.thumb, np.float64).reshape(fp.thumb_rows, fp.thumb_cols, 3),
            what or f"the image of the sensor the force calibration was fitted on ({fp.source})",
            FROM_PRESS_CELLS if fp.from_press else MIN_PRESS_CELLS)


def reference_thumb(model: object) -> tuple[np.ndarray | None, str, float]:
    """(no-contact thumbnail rows x cols x 3, what it is, smallest press blob as a share of the
    grid) the model's bundle carries, or (None, "", 0). A reference taken from the lightest
    calibration press holds that press: only a larger blob (10 % of the grid) reads as a press."""
    bundle = getattr(model, "bundle", None)
    m = getattr(bundle, "manifest", None)
    cal = getattr(m, "force_calibration", None)
    fp = getattr(cal, "sensor", None)
    if fp is not None and fp.thumb:
        return fingerprint_reference(fp)
    ds = getattr(m, "data_stats", None)
    thumb = getattr(ds, "background_thumb", None)
    if ds is not None and thumb:
        return (np.asarray(thumb, np.float64).reshape(ds.thumb_rows, ds.thumb_cols, 3),
                "the no-contact background of the bundle's data statistics", MIN_PRESS_CELLS)
    return None, "", 0.0


def pressed_background(frame_bgr: np.ndarray, ref: np.ndarray, ref_what: str = "the sensor's no-contact image",
                       origin: str = "the given background", tolerance: float = 8.0,
                       min_cells: float = MIN_PRESS_CELLS) -> str:
    """Why ``frame_bgr`` (HxWx3 uint8 BGR, a background about to be used) looks pressed against
    ``ref`` (its sensor's no-contact thumbnail, rows x cols x 3), or "". ``min_cells``: the
    smallest misfit blob, as a share of the grid, that reads as a press."""
    import cv2

    from ..bundle.force_calibration import cells_fitting, look

    thumb = look(frame_bgr)
    if thumb.shape != ref.shape:
        return ""
    fit = cells_fitting(ref, thumb, tolerance)
    if fit.mean() < MIN_SAME_SENSOR_FIT:
        return ""  # another sensor altogether: the calibration's sensor check says so
    bad = (~fit).astype(np.uint8)
    n, labels, stats, cent = cv2.connectedComponentsWithStats(bad, connectivity=8)
    if n < 2:
        return ""
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    area = int(stats[k, cv2.CC_STAT_AREA])
    x, y, w, h = (int(stats[k, i]) for i in (cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH,
                                              cv2.CC_STAT_HEIGHT))
    rows, cols = bad.shape
    borders = (x == 0) + (y == 0) + (x + w == cols) + (y + h == rows)
    if area < max(3, min_cells * bad.size) or borders >= 3:
        return ""
    cx, cy = cent[k]
    return (f"{origin} differs from {ref_what} like a press: {area} of {bad.size} cells around pixel "
            f"({16 * cx + 8:.0f}, {16 * cy + 8:.0f}) do not fit it; a press there reads as no_contact. Give a "
            "no-contact image (sensor untouched), or let the gate learn the background with the gripper open")


def given_background_press(frame_bgr: np.ndarray, model: object, origin: str, stand_in=None) -> str:
    """Why a background about to be used with ``model`` (HxWx3 uint8 BGR) looks pressed, or "".

    Checked as the runtime checks a given background (:func:`reference_thumb`,
    :func:`pressed_background`); when the model's bundle carries no reference, against
    ``stand_in`` (a :class:`~.force_calibration.SensorFingerprint`, e.g. of the lightest
    calibration press, with ``from_press`` set: then only a blob of 10 % of the grid counts);
    "" when there is neither. ``origin`` names the image in the message."""
    ref, what, cells = reference_thumb(model)
    if ref is None and stand_in is not None and stand_in.thumb:
        ref, what, cells = fingerprint_reference(stand_in, stand_in.source)
    if ref is None:
        return ""
    return pressed_background(frame_bgr, ref, what, origin, min_cells=cells)


__all__ = ["fingerprint_reference", "given_background_press", "pressed_background", "reference_thumb"]
