"""Fit a per-sensor force calibration from a few labelled presses (``tactile-force calibrate-force``).

The bundle's model gives its raw (uncalibrated) estimate of every labelled press from the
inputs the runtime gives it (:func:`press_estimates`): an RGB-only model reads the frame (no
gate: each frame is a press the user made); a depth model reads the depth image the runtime's
depth stage makes from the frame and the contact gate's mask, so the presses are replayed
through the runtime ``tactile-force run`` builds (a ``filt_img_depth/`` folder is never read;
a press the runtime gives no force is left out). A monotone map raw -> newtons is fitted and
stored in a new bundle (same ONNX bytes, manifest field ``force_calibration``), which the
runtime applies to every model output.

Fit (numpy only): isotonic regression (pool-adjacent-violators) of the true force on the raw
estimate, knots at each pooled block's mean raw estimate, straight lines between knots; or
``linear`` (least-squares gain and offset). Outside the data the map continues with the
least-squares slope of all frames, down to 0 N and up past the paper's 15 N (to 20 N), so a
press harder than any calibration press still reads higher, and saturates where the runtime
flags it.

Refusals (:class:`CalibrationRefused`, exit code 2), thresholds in :class:`CalibrationLimits`:

- fewer than 8 labelled frames: leave-one-out needs enough points to mean anything;
- true forces spanning less than 3 N: a gain fitted on a narrow range extrapolates wildly;
- Spearman rank correlation of raw estimate vs truth below 0.8: the model does not order
  these presses by force, so no monotone map can make it right (wrong sensor, wrong model,
  or mislabelled frames);
- a non-positive least-squares slope, non-finite estimates or labels;
- a ``--background`` that looks pressed (checked as the runtime checks a given background,
  edge/gate/given_background.py): it would become the sensor's recorded no-contact image.

Leave-one-out (LOO) error before and after: each frame is predicted by a map fitted on the
other frames, so the "after" figure is what an unseen press of the same kind would get.
"""

from __future__ import annotations

import argparse
import copy
import logging
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..bundle.force_calibration import CalibrationFigures, ForceCalibration
from ..bundle.interval import DEFAULT_COVERAGE, IntervalError, fit_interval
from ..errors import TactileForceError

METHODS = ("isotonic", "linear")
#: The calibrated map is extended linearly up to this force (N); the runtime saturates at 15 N.
EXTRAPOLATE_TO_N = 20.0


class CalibrationRefused(TactileForceError, ValueError):
    """The labelled frames cannot support a trustworthy calibration; nothing was written."""


@dataclass(frozen=True)
class CalibrationLimits:
    """When to refuse: at least ``min_frames`` frames, true forces spanning at least
    ``min_span_n`` N, Spearman rank correlation raw vs truth at least ``min_spearman``."""

    min_frames: int = 8
    min_span_n: float = 3.0
    min_spearman: float = 0.8


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    """Spearman rank correlation (average ranks for ties); nan if either is constant."""
    ra, rb = _ranks(np.asarray(a, np.float64)), _ranks(np.asarray(b, np.float64))
    ra, rb = ra - ra.mean(), rb - rb.mean()
    den = float(np.sqrt((ra * ra).sum() * (rb * rb).sum()))
    return float((ra * rb).sum() / den) if den > 0 else float("nan")


def _ranks(x: np.ndarray) -> np.ndarray:
    order = np.argsort(x, kind="stable")
    ranks = np.empty(x.size, np.float64)
    ranks[order] = np.arange(x.size, dtype=np.float64)
    for v in np.unique(x):  # average the ranks of ties
        sel = x == v
        if sel.sum() > 1:
            ranks[sel] = ranks[sel].mean()
    return ranks


def pav(y: np.ndarray, w: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, list[slice]]:
    """Isotonic (non-decreasing) least-squares fit of ``y`` in the given order.

    Returns (fitted values per sample, block values, block slices). Pool-adjacent-violators:
    O(n) amortised."""
    y = np.asarray(y, np.float64)
    w = np.ones_like(y) if w is None else np.asarray(w, np.float64)
    vals: list[float] = []
    wts: list[float] = []
    starts: list[int] = []
    for i in range(y.size):
        vals.append(float(y[i]))
        wts.append(float(w[i]))
        starts.append(i)
        while len(vals) > 1 and vals[-2] > vals[-1]:
            v2, w2 = vals.pop(), wts.pop()
            starts.pop()
            v1, w1 = vals[-1], wts[-1]
            vals[-1] = (v1 * w1 + v2 * w2) / (w1 + w2)
            wts[-1] = w1 + w2
    ends = starts[1:] + [y.size]
    blocks = [slice(s, e) for s, e in zip(starts, ends)]
    fitted = np.empty_like(y)
    for v, b in zip(vals, blocks):
        fitted[b] = v
    return fitted, np.asarray(vals), blocks


def _ls_slope(raw: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Least-squares (slope, intercept) of truth on raw."""
    dx = raw - raw.mean()
    den = float((dx * dx).sum())
    if den <= 0:  # every estimate equal: no slope
        return float("nan"), float("nan")
    slope = float((dx * (truth - truth.mean())).sum() / den)
    return slope, float(truth.mean() - slope * raw.mean())


def fit_knots(raw: np.ndarray, truth: np.ndarray, method: str = "isotonic") -> tuple[list[float], list[float]]:
    """Knots (raw N, force N) of a monotone piecewise-linear map, with the linear extension to
    0 N and :data:`EXTRAPOLATE_TO_N`. CalibrationRefused if no increasing map fits."""
    if method not in METHODS:
        raise CalibrationRefused(f"--method {method!r}; expected one of {', '.join(METHODS)}")
    raw = np.asarray(raw, np.float64)
    truth = np.asarray(truth, np.float64)
    slope, intercept = _ls_slope(raw, truth)
    if not (slope > 0 and np.isfinite(slope)):
        raise CalibrationRefused(f"the true force does not increase with the model's estimate (least-squares slope "
                                 f"{slope:.3g} N/N); check the labels and that the bundle matches this sensor")
    if method == "linear":
        # the fitted line over the data, cut where it leaves 0 .. EXTRAPOLATE_TO_N N
        lo = max(float(raw.min()), -intercept / slope)
        hi = min(float(raw.max()), (EXTRAPOLATE_TO_N - intercept) / slope)
        if not hi > lo:
            raise CalibrationRefused("the least-squares line gives no force between 0 N and "
                                     f"{EXTRAPOLATE_TO_N:g} N over these estimates; check the labels")
        xs, ys = [lo, hi], [slope * lo + intercept, slope * hi + intercept]
    else:
        order = np.argsort(raw, kind="stable")
        r, t = raw[order], truth[order]
        ur, inv = np.unique(r, return_inverse=True)  # equal estimates: one point, mean label
        w = np.bincount(inv).astype(np.float64)
        ut = np.bincount(inv, weights=t) / w
        _, vals, blocks = pav(ut, w)
        xs = [float(np.average(ur[b], weights=w[b])) for b in blocks]
        ys = [float(v) for v in vals]
        if len(xs) < 2:
            raise CalibrationRefused("the isotonic fit pooled every frame into one level: the model's estimate "
                                     "does not order these presses by force")
    ys = [max(0.0, y) for y in ys]  # a force is >= 0 N (rounding can leave -1e-17); still non-decreasing
    # linear extension with the overall least-squares slope
    if ys[0] > 0:
        xs.insert(0, xs[0] - ys[0] / slope)
        ys.insert(0, 0.0)
    if ys[-1] < EXTRAPOLATE_TO_N:
        xs.append(xs[-1] + (EXTRAPOLATE_TO_N - ys[-1]) / slope)
        ys.append(EXTRAPOLATE_TO_N)
    return xs, ys


def _figures(pred: np.ndarray, truth: np.ndarray) -> CalibrationFigures:
    ae = np.abs(pred - truth)
    ok = truth > 0
    re = ae[ok] / truth[ok]
    return CalibrationFigures(re_mean=float(re.mean()), re_std=float(re.std()), mae_mean=float(ae.mean()),
                              mae_std=float(ae.std()), frames=int(truth.size))


def leave_one_out(raw: np.ndarray, truth: np.ndarray, method: str = "isotonic") -> np.ndarray:
    """Calibrated estimate (N) of each frame from a map fitted on all the other frames."""
    raw = np.asarray(raw, np.float64)
    truth = np.asarray(truth, np.float64)
    out = np.empty_like(raw)
    for i in range(raw.size):
        keep = np.arange(raw.size) != i
        xs, ys = fit_knots(raw[keep], truth[keep], method)
        out[i] = ForceCalibration(xs, ys).apply(raw[i:i + 1])[0]
    return out


def fit_force_calibration(raw: np.ndarray, truth: np.ndarray, method: str = "isotonic",
                          limits: CalibrationLimits | None = None, data: str = "",
                          model_sha256: str = "") -> ForceCalibration:
    """Fit and check a calibration from raw estimates and true forces (N), both (N,).

    Parameters
    ----------
    raw, truth
        The bundle's uncalibrated estimate and the measured force of each frame, N.
    method
        'isotonic' (default) or 'linear'.
    limits
        Refusal thresholds (:class:`CalibrationLimits`).
    data, model_sha256
        Recorded in the result: where the frames came from, which model was calibrated.

    Returns
    -------
    ForceCalibration with its knots and the leave-one-out error before and after.

    Raises
    ------
    CalibrationRefused
        Too few frames, too narrow a force range, too weak a rank correlation, bad values.
    """
    lim = limits or CalibrationLimits()
    raw = np.asarray(raw, np.float64).reshape(-1)
    truth = np.asarray(truth, np.float64).reshape(-1)
    if raw.size != truth.size:
        raise CalibrationRefused(f"{raw.size} estimates for {truth.size} labels")
    if not np.all(np.isfinite(truth)):
        raise CalibrationRefused("a true force is NaN or infinite; fix the force files")
    if not np.all(np.isfinite(raw)):
        raise CalibrationRefused("the model gave a non-finite estimate on a calibration frame; check the frames "
                                 "(320x240 BGR DIGIT portrait) and the bundle")
    if raw.size < lim.min_frames:
        raise CalibrationRefused(f"only {raw.size} labelled frame(s); at least {lim.min_frames} are needed "
                                 "(10-30 presses covering the force range you will use)")
    span = float(truth.max() - truth.min())
    if span < lim.min_span_n:
        raise CalibrationRefused(f"the true forces span only {span:.2f} N ({truth.min():.2f} to {truth.max():.2f} N); "
                                 f"at least {lim.min_span_n:g} N is needed: press from light to firm")
    rho = spearman(raw, truth)
    if not (rho >= lim.min_spearman):
        raise CalibrationRefused(f"the model's estimate is not monotone enough in the true force (Spearman rank "
                                 f"correlation {rho:.2f} < {lim.min_spearman:g}); a monotone calibration cannot fix "
                                 "that: check the labels, that frames and forces are paired, and the bundle")
    xs, ys = fit_knots(raw, truth, method)
    after = leave_one_out(raw, truth, method)
    cal = ForceCalibration(raw_n=xs, force_n=ys, method=method, frames=int(raw.size), data=data,
                           force_range_n=[float(truth.min()), float(truth.max())], spearman=rho,
                           model_sha256=model_sha256, loo_before=_figures(raw, truth),
                           loo_after=_figures(after, truth))
    cal.check()
    return cal


# ----------------------------------------------------------------------------- frames and bundles

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
        from ..sources.files import load_background

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


# ----------------------------------------------------------------------------- CLI

def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bundle", help="model bundle to calibrate (folder with model.onnx + model.json)")
    parser.add_argument("--data", required=True,
                        help="labelled presses in the authors' layout (images/N.png + forces/force_N.txt), "
                             "e.g. what 'tactile-force record' writes; 10-30 presses from light to firm")
    parser.add_argument("--out", required=True, help="folder for the calibrated bundle (new)")
    parser.add_argument("--method", choices=METHODS, default="isotonic",
                        help="monotone map: isotonic (default; piecewise linear) or linear (gain + offset)")
    parser.add_argument("--force", action="store_true", help="replace --out if it exists")
    parser.add_argument("--sensor", default="", metavar="SERIAL",
                        help="serial of the sensor the presses come from (default: the one 'record' wrote in "
                             "meta.jsonl); the runtime flags readings of another sensor out_of_distribution")
    parser.add_argument("--background", default=None, metavar="NO_CONTACT.png",
                        help="no-contact image of the same sensor: its fingerprint is recorded with the calibration "
                             "(default: the lightest press stands in for it); a depth bundle's presses are judged "
                             "against it as 'run --background' does (default: learnt from the first frames, as 'run' "
                             "does); refused when it looks pressed")
    parser.add_argument("--coverage", type=float, default=DEFAULT_COVERAGE,
                        help="coverage of every reading's interval, fitted on the leave-one-out predictions "
                             f"(default {DEFAULT_COVERAGE:g}; 0 < c < 1)")


def plot_path(out: str | os.PathLike) -> Path:
    """Where calibrate-force draws its plot: beside the new bundle, ``<out>_calibration.png``."""
    p = Path(out)
    return p.with_name(f"{p.name}_calibration.png")


def main(args: argparse.Namespace) -> int:
    from ..errors import BundleError

    try:
        plot = plot_path(args.out)
        bundle, cal = calibrate_bundle(args.bundle, args.data, args.out, args.method, overwrite=args.force,
                                       coverage=getattr(args, "coverage", DEFAULT_COVERAGE), plot=plot,
                                       sensor=getattr(args, "sensor", ""), background=getattr(args, "background", None))
    except IntervalError as exc:
        print(f"tactile-force calibrate-force: error: --coverage: {exc}", file=sys.stderr)
        return 2
    except CalibrationRefused as exc:
        print(f"tactile-force calibrate-force: refused: {exc}", file=sys.stderr)
        return 2
    except BundleError as exc:
        print(f"tactile-force calibrate-force: error: {exc}", file=sys.stderr)
        return 2
    b, a = cal.loo_before, cal.loo_after
    assert b is not None and a is not None
    print(f"calibrated on {cal.data}: true force {cal.force_range_n[0]:.2f} to {cal.force_range_n[1]:.2f} N, "
          f"Spearman {cal.spearman:.3f}, {cal.method} map with {len(cal.raw_n)} knots")
    for label, f in (("before (raw)", b), ("after       ", a)):
        print(f"leave-one-out  {label}: RE {f.re_mean:.3f} +- {f.re_std:.3f}, "
              f"MAE {f.mae_mean:.2f} +- {f.mae_std:.2f} N")
    if cal.sensor is not None:
        print(f"sensor: {cal.sensor.serial or 'serial unknown'}; fingerprint from {cal.sensor.source} (readings of "
              "another sensor are flagged out_of_distribution)")
    iv = bundle.manifest.interval
    if iv is not None:
        q = [b.q for b in iv.bins]
        print(f"interval ({iv.coverage:g} coverage, split conformal on the {iv.n} leave-one-out predictions): " + (
            f"+- {max(v for v in q if v is not None):.3f} x max(estimate, {iv.scale_floor_n:g} N)" if iv.known else
            "unknown: too few presses for this coverage (readings carry no interval)"))
    print(f"wrote {bundle.path} and {plot} (raw and calibrated estimates vs true force, the fitted map)")
    return 0
