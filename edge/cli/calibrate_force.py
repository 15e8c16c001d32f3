"""CLI: ``tactile-force calibrate-force BUNDLE --data PRESSES --out DIR``: fit a per-sensor force
calibration from 10-30 labelled presses into a new bundle (:mod:`tactile_force.edge.fitting.calibrate`)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..bundle.interval import DEFAULT_COVERAGE, IntervalError
from ..fitting.calibrate import calibrate_bundle
from ..fitting.force_calibration import METHODS, CalibrationRefused
from .args import float_in


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bundle", help="model bundle to calibrate (folder with model.onnx + model.json), or 'default' "
                                       "(the embedded default model)")
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
    parser.add_argument("--coverage", type=float_in(0.0, 1.0, low_open=True, high_open=True), default=DEFAULT_COVERAGE,
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
        source = args.bundle
        if source == "default":  # as run --bundle default: the embedded default model
            from ..scene import default_bundle_path

            source = default_bundle_path()
        bundle, cal = calibrate_bundle(source, args.data, args.out, args.method, overwrite=args.force,
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
