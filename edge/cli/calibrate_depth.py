"""``tactile-force calibrate-depth``: ball presses -> our colour->normal LUT file + report.

Presses: a folder of PNG/JPG frames (circles detected automatically) or an .npz with
``imgs`` (N x H x W x 3 uint8 BGR) and optionally ``f0`` (background), ``touch_center``
(N x 2, x y) and ``touch_radius`` (N,) in pixels.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import cv2
import numpy as np

from ..depth.calibration import (
    Circle,
    LUTOptions,
    Press,
    check_circle_scale,
    detect_press_circle,
    evaluate_lut,
    fit_lut,
)
from ..depth.overlay import PressRole, PressTile, circle_sheet, write_image
from ..errors import DatasetError
from ..files.guard import OutputKind, check_input, check_output
from ..report.progress import progress
from ..typed_json import Check
from .args import float_in, within


def overlay_path(output: str, overlay: str | None) -> Path:
    """Where the circle image goes: ``overlay`` when given, else next to the output
    (``cal.npz`` -> ``cal_circles.png``). DatasetError for an image suffix OpenCV cannot write."""
    if overlay:
        p = Path(overlay)
        if p.suffix.lower() not in (".png", ".jpg", ".jpeg"):
            raise DatasetError(f"--overlay {overlay}: expected a .png or .jpg file name")
        return p
    out = Path(output)
    return out.with_name(out.stem + "_circles.png")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("presses", help="folder of ball-press images, or .npz (imgs, f0, touch_center, touch_radius)")
    parser.add_argument("--background", help="no-contact frame (image file); default: f0 of the .npz")
    parser.add_argument("--ball-radius-mm", type=float_in(0.0, 1000.0, low_open=True), required=True,
                        help="calibration ball radius, mm (a finite number > 0)")
    parser.add_argument("--px-per-mm", type=float_in(0.0, 10_000.0, low_open=True), required=True,
                        help="image scale, pixels per mm (a finite number > 0); the detected contact circles are "
                             "checked against the ball's size in pixels (radius x scale)")
    parser.add_argument("--holdout", type=float_in(0.0, 1.0, low_open=True, high_open=True), default=0.25,
                        help="share of presses held out for the report (0 < share < 1)")
    parser.add_argument("--detect", action="store_true", help="detect circles even when the .npz has labels")
    parser.add_argument("--bins", type=within(int, Check(ge=2, le=256)), default=32,
                        help="LUT bins per colour channel (>= 2)")
    parser.add_argument("--bin-width", type=float_in(0.0, 256.0, low_open=True), default=6.0,
                        help="colour levels per LUT bin")
    parser.add_argument("-o", "--output", required=True, help="calibration file to write (.npz)")
    parser.add_argument("--force", action="store_true", help="replace --output (and the circle image) if they exist")
    parser.add_argument("--overlay", metavar="PATH",
                        help="image of the presses with the detected ball circles, to check them "
                             "(.png or .jpg; default: OUTPUT with the suffix _circles.png)")


def _read(path: Path) -> np.ndarray:
    check_input(path, "image", "an image file")
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise DatasetError(f"{path}: cannot decode image (empty, truncated or not an image)")
    return img


def load_presses(src: str, background: str | None) -> tuple[list[Press], np.ndarray]:
    p = check_input(src, "presses", "a folder of images or an .npz file")
    bg = _read(Path(background)) if background else None
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in (".png", ".jpg", ".jpeg"))
        if not files:
            raise DatasetError(f"{p}: no .png/.jpg ball presses")
        presses = [Press(_read(f), None, f.name) for f in files]
    elif p.is_file():
        try:
            z = np.load(p)
            imgs = z["imgs"]
        except Exception as exc:
            raise DatasetError(f"{p}: cannot read ball presses ({exc}); expected .npz with 'imgs'") from None
        centers = z["touch_center"] if "touch_center" in z.files else None
        radii = z["touch_radius"] if "touch_radius" in z.files else None
        presses = []
        for i, img in enumerate(imgs):
            c = None
            if centers is not None and radii is not None:
                c = Circle(float(centers[i][0]), float(centers[i][1]), float(radii[i]))
            presses.append(Press(np.ascontiguousarray(img), c, f"{p.name}[{i}]"))
        if bg is None and "f0" in z.files:
            bg = z["f0"]
    else:
        raise DatasetError(f"{p}: not found (expected a folder of images or an .npz)")
    if bg is None:
        raise DatasetError("no background frame: pass --background (a no-contact frame)")
    for pr in presses:
        if pr.frame.shape != bg.shape:
            raise DatasetError(f"press {pr.name}: shape {pr.frame.shape} differs from the background {bg.shape}")
    return presses, bg


def main(args: argparse.Namespace) -> int:
    overlay = overlay_path(args.output, args.overlay)
    inputs = [("presses", args.presses), ("--background", args.background)]
    check_output(args.output, inputs, force=args.force, kind=OutputKind.FILE, flag="--output")
    check_output(overlay, inputs, force=args.force, kind=OutputKind.FILE, flag="--overlay")
    presses, bg = load_presses(args.presses, args.background)
    ball_px = args.ball_radius_mm * args.px_per_mm
    found: list[Press] = []
    skipped: list[Press] = []
    for pr in progress(presses, desc="detecting circles"):
        c = pr.circle
        if c is None or args.detect:
            c = detect_press_circle(pr.frame, bg)
        if c is None:
            print(f"  {pr.name}: no contact circle found, skipped")
            skipped.append(pr)
            continue
        found.append(Press(pr.frame, c, pr.name))
    n_test = max(1, int(round(len(found) * args.holdout)))
    # Every k-th press is held out so train and test cover the gel alike.
    step = len(found) / n_test
    test_i = {int(i * step + step / 2) for i in range(n_test)}
    # The circle image is written first, also when too few circles were found: it shows why.
    tiles = [PressTile(p.frame, p.circle, p.name, PressRole.HELDOUT if i in test_i else PressRole.FIT)
             for i, p in enumerate(found)] + [PressTile(p.frame, None, p.name, PressRole.SKIPPED) for p in skipped]
    order = {p.name: k for k, p in enumerate(presses)}
    tiles.sort(key=lambda t: order.get(t.name, 0))
    write_image(overlay, circle_sheet(tiles))
    print(f"  circles drawn on the presses: {overlay} (green: fit, orange: held out, red cross: no circle)")
    if len(found) < 2:
        raise DatasetError(f"only {len(found)} presses with a circle; need at least 2 (one to fit, one to test); "
                           f"see {overlay}")
    check_circle_scale([p.circle for p in found if p.circle is not None], bg.shape[:2], args.ball_radius_mm,
                       args.px_per_mm, see=str(overlay))
    train = [p for i, p in enumerate(found) if i not in test_i]
    test = [p for i, p in enumerate(found) if i in test_i]
    lut = fit_lut(train, bg, ball_px, LUTOptions(bins=args.bins, bin_width=args.bin_width))
    err_train = evaluate_lut(lut, train, ball_px)
    err_test = evaluate_lut(lut, test, ball_px)
    lut.px_per_mm = args.px_per_mm
    lut.ball_radius_mm = args.ball_radius_mm
    def angles(e) -> dict[str, float]:
        return {"mean": e.mean_deg, "median": e.median_deg, "p90": e.p90_deg}

    lut.report = {"train_presses": len(train), "test_presses": len(test), "ball_radius_px": ball_px,
                  "train_angle_deg": angles(err_train), "heldout_angle_deg": angles(err_test)}
    out = lut.save(args.output)
    print(f"calibrate-depth: {len(found)}/{len(presses)} presses with a circle; "
          f"fit on {len(train)}, held out {len(test)}")
    for label, e in (("fit presses:      ", err_train), ("held-out presses: ", err_test)):
        print(f"  normal angle error, {label}  mean {e.mean_deg:5.2f} deg  median {e.median_deg:5.2f}  "
              f"p90 {e.p90_deg:5.2f}")
    print(f"  wrote {out}")
    print(json.dumps(lut.report))
    return 0
