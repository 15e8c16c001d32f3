"""``tactile-force devices`` and ``tactile-force record``."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..edge.errors import SourceError
from .discovery import UDEV_INSTALL_HINT, discover, udev_rules_path


def configure_devices(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.add_argument("--sys-root", default="/sys", help="sysfs mount point (default /sys)")
    parser.add_argument("--dev-root", default="/dev", help="device folder (default /dev)")


def _scales() -> tuple[list[dict], str]:
    try:
        from .hid_scale import find_scales

        return find_scales(), ""
    except ImportError as exc:
        return [], str(exc)
    except OSError as exc:
        return [], f"hidapi cannot enumerate HID devices ({exc})"


def main_devices(args: argparse.Namespace) -> int:
    result = discover(args.sys_root, args.dev_root)
    scales, scale_note = _scales()
    if args.json:
        print(json.dumps({
            "method": result.method, "note": result.note,
            "devices": [{"kind": d.kind.value, "serial": d.serial, "vendor_id": f"{d.info.vendor_id:04x}",
                         "product_id": f"{d.info.product_id:04x}", "firmware_revision": d.firmware_revision,
                         "speed_mbps": d.info.speed_mbps, "video_nodes": d.info.video_nodes,
                         "streamable": d.streamable, "problems": d.problems} for d in result.devices],
            "scales": [{"vendor_id": f"{s['vendor_id']:04x}", "product_id": f"{s['product_id']:04x}",
                        "product": s.get("product_string")} for s in scales],
            "scale_note": scale_note,
        }, indent=2))
        return 0
    print("USB devices" + (f" (read via {result.method}):" if result.method != "none" else ":"))
    if not result.devices:
        print("  no DIGIT, GelSight Mini or OAK attached to this host.")
        if result.note:
            print(f"  ({result.note})")
    for d in result.devices:
        print("  " + d.describe())
        for p in d.problems:
            print(f"    ! {p}")
    if scales:
        print("USB scales (HID usage page 0x8D):")
        for s in scales:
            print(f"  {s['vendor_id']:04x}:{s['product_id']:04x}  {s.get('product_string') or ''}  {s.get('path')!r}")
    else:
        print("USB scales: none found" + (f" ({scale_note})" if scale_note else ""))
    if any(d.needs_udev_rule for d in result.devices):
        print(f"\nPermission problems: {UDEV_INSTALL_HINT}\nRules file: {udev_rules_path()}")
    return 0


def configure_record(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--sensor", required=True, help="DIGIT serial (D12345), index (0) or /dev/videoN")
    parser.add_argument("--scale", default="auto", help="'auto' (first HID scale) or VID:PID in hex, e.g. 0922:8003")
    parser.add_argument("--out", required=True, type=Path, help="dataset folder (authors' layout; resumed if present)")
    parser.add_argument("--max", type=int, default=None, help="stop after this many samples")
    parser.add_argument("--every", type=int, default=1, help="keep every n-th frame (default 1)")
    parser.add_argument("--stable-only", action="store_true", help="skip frames while the scale reports motion")
    parser.add_argument("--min-force", type=float, default=None, help="skip frames below this reference force, N")
    parser.add_argument("--tare", action="store_true", help="take the scale's current stable reading as zero first")
    parser.add_argument("--resolution", default="QVGA", choices=["QVGA", "VGA"])
    parser.add_argument("--fps", type=int, default=60, help="QVGA: 60 or 30; VGA: 30 or 15")
    parser.add_argument("--intensity", default=None, help="LED r,g,b each 0..15 (firmware >= 200)")


def _scale_options(text: str):
    from .hid_scale import ScaleOptions

    if text == "auto":
        return ScaleOptions()
    try:
        vid, pid = (int(x, 16) for x in text.split(":"))
    except ValueError:
        raise SourceError(f"--scale {text!r}: expected 'auto' or VID:PID in hex (e.g. 0922:8003)") from None
    return ScaleOptions(vendor_id=vid, product_id=pid)


def main_record(args: argparse.Namespace) -> int:
    from .digit import DigitOptions, DigitSource
    from .hid_scale import HidScale
    from .recorder import RecordOptions, record

    intensity = None
    if args.intensity:
        try:
            intensity = tuple(int(x) for x in args.intensity.split(","))
        except ValueError:
            raise SourceError(f"--intensity {args.intensity!r}: expected r,g,b integers 0..15") from None
    try:
        digit_options = DigitOptions(sensor=args.sensor, resolution=args.resolution, fps=args.fps, intensity=intensity)
        digit_options.validate()
    except ValueError as exc:
        raise SourceError(str(exc)) from None
    with DigitSource(digit_options) as source:
        scale = HidScale.open(_scale_options(args.scale))
        try:
            if args.tare:
                print(f"tare: {scale.tare():.3f} N taken as zero")
            print(f"recording DIGIT {source.name} ({source.node}) with scale {scale.name} into {args.out}; "
                  "Ctrl-C to stop")
            result = record(source, scale, RecordOptions(out=args.out, max_samples=args.max, every_n=args.every,
                                                         stable_only=args.stable_only, min_force_n=args.min_force))
        finally:
            scale.close()
    if result.removed_unlabelled:
        print(f"removed {len(result.removed_unlabelled)} unlabelled frame(s) left by an earlier interrupted run")
    ids = result.written
    span = f" (ids {ids[0]}..{ids[-1]})" if ids else ""
    print(f"wrote {len(ids)} sample(s){span} to {result.out}; stopped: {result.stopped_by}")
    if result.skipped:
        print("skipped: " + ", ".join(f"{k}: {v}" for k, v in result.skipped.items()))
    return 0 if not result.stopped_by.startswith(("sensor lost", "scale lost")) else 1
