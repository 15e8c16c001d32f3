"""Calibrating a bundle on a few labelled presses (the work of ``tactile-force calibrate-force``).

The bundle's model gives its raw (uncalibrated) estimate of every labelled press from the
inputs the runtime gives it (:func:`press_estimates`): an RGB-only model reads the frame (no
gate: each frame is a press the user made); a depth model reads the depth image the runtime's
depth stage makes from the frame and the contact gate's mask, so the presses are replayed
through the runtime ``tactile-force run`` builds (a ``filt_img_depth/`` folder is never read;
a press the runtime gives no force is left out). A monotone map raw -> newtons is fitted
(:mod:`.force_calibration`) and stored in a new bundle (same ONNX bytes, manifest field
``force_calibration``), which the runtime applies to every model output. A ``--background``
that looks pressed is refused (checked as the runtime checks a given background,
edge/gate/given_background.py): it would become the sensor's recorded no-contact image.
"""

from __future__ import annotations

import copy
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..bundle.interval import DEFAULT_COVERAGE
from ..errors import TactileForceError
from .force_calibration import (
    CalibrationLimits,
    CalibrationRefused,
    fit_force_calibration,
    leave_one_out,
)
from .interval import fit_interval


@dataclass
class LabelledFrames:
    """Labelled frames: rgb (N,320,240,3) uint8 BGR, force (N,) N. Depth images are never read
    from the data: a depth bundle's are made by the runtime (:func:`press_estimates`)."""

    rgb: np.ndarray
    force: np.ndarray
    source: str


def read_labelled(root: str | os.PathLike) -> LabelledFrames:
    """Frames and forces from the authors' layout (which ``tactile-force record`` writes:
    ``images/N.png`` + ``forces/force_N.txt``; a ``filt_img_depth/`` folder is not read)."""
    from ..data.dataset import AuthorsDataset
    from ..data.labels import unit_problem
    from ..errors import DatasetError
    from ..frames import check_frame

    p = Path(root)
    if not p.is_dir():
        raise CalibrationRefused(f"--data {p}: folder not found (expected images/N.png + forces/force_N.txt)")
    try:
        ds = AuthorsDataset(p, require_depth=False)
        samples = [ds.load(n) for n in ds.ids]
        ds.check_unique(samples)  # a copied press would make the leave-one-out error read near zero
    except DatasetError as exc:
        raise CalibrationRefused(f"--data: {exc}") from None
    if (problem := unit_problem([s.force_n for s in samples], f"--data {p}")) is not None:
        logging.getLogger(__name__).warning(problem)
    for s in samples:
        try:
            check_frame(s.frame)
        except TactileForceError as exc:
            raise CalibrationRefused(f"{ds.image_path(s.id)}: {exc}") from None
    return LabelledFrames(np.stack([s.frame for s in samples]), np.array([s.force_n for s in samples], np.float64),
                          f"{p} ({len(samples)} frames)")


def _lightest_press(frames: LabelledFrames, serial: str = ""):
    """The fingerprint of the lightest press (least contact), standing in for a no-contact image."""
    from ..bundle.force_calibration import sensor_fingerprint

    k = int(np.argmin(frames.force))
    fp = sensor_fingerprint(frames.rgb[k], serial, f"the lightest press of {frames.source} ({frames.force[k]:.2f} N)")
    fp.from_press = True
    return fp


def sensor_record(data: str | os.PathLike, frames: LabelledFrames, serial: str = "",
                  background: str | os.PathLike | None = None, model: object | None = None):
    """The :class:`~.force_calibration.SensorFingerprint` of the sensor the presses in ``data``
    were recorded on: ``serial`` (else the single ``sensor`` that ``record`` wrote in
    ``meta.jsonl``, else unknown) and the fingerprint of ``background`` (a no-contact image of
    it), else of the lightest press (least contact). Raises :class:`CalibrationRefused` for an
    unreadable background, presses whose meta names several sensors, or (with ``model``, the
    bundle being calibrated) a background that looks pressed: checked as the runtime checks a
    given background, against the bundle's no-contact reference, else against the lightest
    press (:func:`~.background_check.given_background_press`)."""
    import json

    from ..bundle.force_calibration import sensor_fingerprint

    meta = Path(data) / "meta.jsonl"
    if not serial and meta.is_file():
        names = set()
        for line in meta.read_text(errors="replace").splitlines():
            try:
                rec = json.loads(line)
            except ValueError:
                continue
            if isinstance(rec, dict) and rec.get("sensor"):
                names.add(str(rec["sensor"]))
        if len(names) > 1:
            raise CalibrationRefused(f"--data {data}: meta.jsonl names several sensors {sorted(names)}; a force "
                                     "calibration belongs to one sensor (pass --sensor SERIAL to choose)")
        serial = names.pop() if names else ""
    if background is not None:
        from ..errors import SourceError
        from ..gate.given_background import given_background_press
        from ..sources import load_background

        try:
            frame = load_background(background)[0]
        except SourceError as exc:
            raise CalibrationRefused(f"--background: {exc}") from None
        if frame.shape != frames.rgb.shape[1:]:
            raise CalibrationRefused(f"--background {background}: {frame.shape[1]}x{frame.shape[0]} image; the "
                                     f"presses are {frames.rgb.shape[2]}x{frames.rgb.shape[1]} (one sensor, one size)")
        if model is not None:
            why = given_background_press(frame, model, f"--background {background}", _lightest_press(frames, serial))
            if why:
                raise CalibrationRefused(f"{why} (it would be recorded as the sensor's no-contact image, and a depth "
                                         "bundle's contact masks are made against it)")
        return sensor_fingerprint(frame, serial, f"--background {background}")
    fp = _lightest_press(frames, serial)
    logging.getLogger(__name__).warning(
        "calibrate-force: no --background: the sensor's fingerprint is taken from the lightest press (%.2f N); a "
        "no-contact image of the sensor (--background NO_CONTACT.png) makes it exact", float(np.min(frames.force)))
    return fp


def raw_estimates(model, frames: LabelledFrames) -> np.ndarray:
    """Estimates (N,) of an RGB-only OnnxForceModel on every frame (uncalibrated when loaded
    with ``calibrate=False``): the frame is all such a model reads, so these are the estimates
    the runtime gives those frames. Depth models: :func:`press_estimates`."""
    if model.needs_depth:
        raise ValueError("raw_estimates: a depth model reads the depth the runtime makes; use press_estimates")
    out = np.empty(len(frames.force), np.float64)
    for i in range(0, out.size, 2):
        out[i:i + 2] = model.predict(frames.rgb[i:i + 2])
    return out


def press_estimates(bundle_path: str | os.PathLike, model, frames: LabelledFrames, data: str | os.PathLike,
                    background: str | os.PathLike | None = None) -> tuple[np.ndarray, list[str]]:
    """The uncalibrated estimate of every press from the inputs the runtime gives the model.

    An RGB-only model reads the frame itself (:func:`raw_estimates`). A depth model (D, Dmod,
    RGBmod+D) reads the depth image the runtime's depth stage makes from the frame and the
    contact gate's mask: the presses in ``data`` are replayed through the same runtime
    ``tactile-force run --source DATA --bundle BUNDLE [--background BG]`` builds
    (:func:`tactile_force.edge.runtime.replay.replay_readings`, the bundle's calibration not
    applied), against ``background`` when given, else the background the gate learns from the
    first frames, as ``run`` does. A press the runtime gives no force (the gate saw no
    contact, it was learning its background, the depth stage failed) has no estimate.

    Returns
    -------
    tuple of (numpy.ndarray, list of str)
        The estimates (N,) in N (NaN where there is none) and, per press, why it has none
        ("" = it has one).
    """
    if not model.needs_depth:
        return raw_estimates(model, frames), [""] * len(frames.force)
    from ..runtime.replay import replay_readings

    readings = replay_readings(Path(bundle_path), Path(data), Path(background) if background is not None else None,
                               warn=logging.getLogger(__name__).warning, calibrate=False)
    by_index = {r.frame_index: r for r in readings}
    raw = np.full(len(frames.force), np.nan)
    why = ["not read by the runtime"] * len(frames.force)
    for i in range(raw.size):
        r = by_index.get(i)
        if r is None:
            continue
        if r.raw_force_n == r.raw_force_n:  # the CNN ran on the runtime's inputs
            raw[i], why[i] = float(r.raw_force_n), ""
        else:
            why[i] = "|".join(r.flags.names()) + (f" ({r.detail})" if r.detail else "")
    return raw, why


def calibrate_bundle(bundle_path: str | os.PathLike, data: str | os.PathLike, out: str | os.PathLike,
                     method: str = "isotonic", limits: CalibrationLimits | None = None, overwrite: bool = False,
                     coverage: float = DEFAULT_COVERAGE, plot: str | os.PathLike | None = None,
                     sensor: str = "", background: str | os.PathLike | None = None):
    """Fit a calibration for the bundle on the labelled frames in ``data``; write a new bundle at ``out``.

    Returns (written Bundle, ForceCalibration). The new bundle holds the same ONNX bytes;
    an existing calibration in the source bundle is replaced (the fit uses raw estimates),
    and so is its ``interval``: refitted with ``coverage`` on the leave-one-out predictions
    (:func:`tactile_force.edge.bundle.interval.fit_interval`). ``plot``: also draw the raw and the
    leave-one-out calibrated estimates against the true force, with the fitted map, to this PNG
    (:func:`tactile_force.edge.report.plots.calibration_plot`). The calibration records the sensor
    it was fitted on (:func:`sensor_record`): ``sensor`` (its serial; default: the one
    ``record`` wrote in ``meta.jsonl``) and a fingerprint of ``background`` (a no-contact
    frame of it; default: the lightest press), so the runtime flags another sensor."""
    from ..bundle.manifest import ErrorFigures, ErrorReport, SourceRef
    from ..bundle.store import load_bundle, write_bundle
    from ..files.guard import OutputKind, check_output
    from ..model.onnx_model import OnnxForceModel

    inputs = [("bundle", bundle_path), ("--data", data), ("--background", background)]
    dest = check_output(out, inputs, force=overwrite, kind=OutputKind.BUNDLE)
    if plot is not None:  # an output too: a user's file of that name is replaced only with --force
        check_output(plot, inputs, force=overwrite, kind=OutputKind.FILE, flag="the calibration plot")
    src = load_bundle(bundle_path)
    model = OnnxForceModel(src, threads=1, calibrate=False)
    frames = read_labelled(data)
    fingerprint = sensor_record(data, frames, sensor, background, model)  # a pressed background: refused here
    raw, why = press_estimates(src.path, model, frames, data, background)
    frames = _with_estimates(frames, why, limits or CalibrationLimits(), data)
    raw = raw[[not w for w in why]]
    cal = fit_force_calibration(raw, frames.force, method, limits, data=frames.source,
                                model_sha256=src.manifest.sha256)
    cal.sensor = fingerprint
    manifest = copy.deepcopy(src.manifest)
    manifest.force_calibration = cal
    manifest.name = dest.name
    manifest.provenance.calibrated_from = SourceRef(bundle=src.name, sha256=src.manifest.sha256)
    # The source's error figures describe the uncalibrated output; the calibrated bundle's
    # error is the leave-one-out error on this sensor's presses.
    after = cal.loo_after
    assert after is not None
    manifest.error = ErrorReport(data=f"leave-one-out on {frames.source}", frames=after.frames,
                                 vs_truth=ErrorFigures(n=after.frames, re_mean=after.re_mean, re_std=after.re_std,
                                                       mae_mean=after.mae_mean, mae_std=after.mae_std))
    # The interval is REPLACED by one fitted on this sensor's presses: the leave-one-out
    # predictions are what an unseen press gets, so they are the conformal calibration set
    # (few presses: one bin; too few for the coverage: 'unknown'; edge/bundle/interval.py).
    manifest.interval = fit_interval(leave_one_out(raw, frames.force, method), frames.force, coverage,
                                     model_sha256=src.manifest.sha256,
                                     data=f"leave-one-out predictions of calibrate-force on {frames.source}")
    if plot is not None:
        from ..report.plots import calibration_plot

        calibration_plot(frames.force, raw, leave_one_out(raw, frames.force, method), np.asarray(cal.raw_n),
                         np.asarray(cal.force_n), plot)
    return write_bundle(dest, src.onnx_path.read_bytes(), manifest, overwrite=overwrite, inputs=inputs), cal


def _with_estimates(frames: LabelledFrames, why: list[str], limits: CalibrationLimits,
                    data: str | os.PathLike) -> LabelledFrames:
    """The presses the runtime gave a force (``why`` "" for them): the others are left out of
    the fit with a warning (the runtime never applies the map to them); refused when fewer than
    ``limits.min_frames`` remain."""
    keep = np.array([not w for w in why], bool)
    if keep.all():
        return frames
    reasons: dict[str, int] = {}
    for w in why:
        if w:
            reasons[w] = reasons.get(w, 0) + 1
    said = "; ".join(f"{n} x {w}" for w, n in sorted(reasons.items(), key=lambda kv: -kv[1]))
    n, k = keep.size, int(keep.sum())
    if k < limits.min_frames:
        raise CalibrationRefused(
            f"only {k} of the {n} presses got a force estimate through the runtime (the others: {said}); at least "
            f"{limits.min_frames} are needed. A depth bundle reads the depth the runtime makes from each frame's "
            "contact against the sensor's no-contact image: give --background NO_CONTACT.png (the sensor untouched)"
            ", or record a few frames without contact first (the runtime learns its background from them)")
    logging.getLogger(__name__).warning(
        "calibrate-force: %d of the %d presses got no force estimate through the runtime (%s); the map is fitted "
        "on the other %d (the runtime never applies it to such frames)", n - k, n, said, k)
    return LabelledFrames(frames.rgb[keep], frames.force[keep],
                          f"{Path(data)} ({k} of {n} frames with a runtime estimate)")
