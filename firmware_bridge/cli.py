"""``tactile-force devices`` and ``tactile-force record``."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from tactile_force.edge.cli.args import within
from tactile_force.edge.errors import SourceError
from tactile_force.edge.limits import COUNT, FORCE_N, FRAME_COUNT, MAX_FPS
from tactile_force.edge.typed_json import Check

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
    parser.description = (
        "Record DIGIT frames labelled with a USB HID scale's force into a dataset in the authors' layout.\n\n"
        "Recording into a folder that holds samples resumes it: first the folder is repaired (temp files and\n"
        "frames whose label never landed are removed, a meta.jsonl line cut short by a power cut is dropped).\n"
        "A full disk stops the recording cleanly (exit 1), keeping every sample written before it.\n"
        "'--repair DIR' does only the repair, without any hardware attached.")
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("--repair", type=Path, metavar="DIR",
                        help="repair a recording folder after a crash (no sensor or scale needed) and exit")
    parser.add_argument("--sensor", help="DIGIT serial (D12345), index (0) or /dev/videoN (required to record)")
    parser.add_argument("--scale", default="auto", help="'auto' (first HID scale) or VID:PID in hex, e.g. 0922:8003")
    parser.add_argument("--out", type=Path,
                        help="dataset folder (authors' layout; resumed if present; required to record)")
    parser.add_argument("--max", type=within(int, FRAME_COUNT), default=None, help="stop after this many samples")
    parser.add_argument("--every", type=within(int, COUNT), default=1, help="keep every n-th frame (default 1)")
    parser.add_argument("--stable-only", action="store_true", help="skip frames while the scale reports motion")
    parser.add_argument("--min-force", type=within(float, FORCE_N), default=None,
                        help="skip frames below this reference force, N")
    parser.add_argument("--tare", action="store_true", help="take the scale's current stable reading as zero first")
    parser.add_argument("--resolution", default="QVGA", choices=["QVGA", "VGA"])
    parser.add_argument("--fps", type=within(int, Check(ge=1, le=int(MAX_FPS))), default=60,
                        help="QVGA: 60 or 30; VGA: 30 or 15")
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


def main_repair(root: Path) -> int:
    """``record --repair DIR``: repair, then check every label and meta line; 0 when the folder reads."""
    from tactile_force.edge.data.dataset import AuthorsDataset
    from tactile_force.edge.errors import DatasetError

    from .recorder import repair_dataset

    if not (root / "images").is_dir():
        print(f"tactile-force record: error: --repair {root}: not a recording folder (no images/ inside)",
              file=sys.stderr)
        return 2
    from tactile_force.edge.files.claim import OutputClaim

    with OutputClaim(root, "record", flag="--repair", inside=True):  # never while a recorder writes there
        print(repair_dataset(root).describe())
    try:
        data = AuthorsDataset(root)
        data.forces()
    except DatasetError as exc:
        print(f"tactile-force record: the folder still does not read: {exc}", file=sys.stderr)
        return 1
    print(f"{root}: {len(data)} labelled sample(s) read back")
    return 0


def main_record(args: argparse.Namespace) -> int:
    from .digit import DigitOptions, DigitSource
    from .hid_scale import HidScale
    from .recorder import RecordOptions, record

    if args.repair is not None:
        return main_repair(args.repair)
    missing = [flag for flag, v in (("--sensor", args.sensor), ("--out", args.out)) if not v]
    if missing:
        print(f"tactile-force record: error: {' and '.join(missing)} required to record "
              "(or --repair DIR to repair a folder)", file=sys.stderr)
        return 2
    intensity = None
    if args.intensity:
        try:
            r, g, b = (int(x) for x in args.intensity.split(","))
            intensity = (r, g, b)
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
    for rep in result.repairs:
        if rep.changed:
            print(f"repaired: {rep.describe()}")
    ids = result.written
    span = f" (ids {ids[0]}..{ids[-1]})" if ids else ""
    print(f"wrote {len(ids)} sample(s){span} to {result.out}; stopped: {result.stopped_by}")
    if result.skipped:
        print("skipped: " + ", ".join(f"{k}: {v}" for k, v in result.skipped.items()))
    if result.write_failed:
        print(f"tactile-force record: error: {result.out}: {result.stopped_by}; the {len(ids)} sample(s) written "
              "before it are kept and readable. Free some space and run the same command again to resume.",
              file=sys.stderr)
        return 1
    if result.signal is not None:  # every sample written before the signal is whole and kept
        return 128 + int(result.signal)
    return 0 if not result.stopped_by.startswith(("sensor lost", "scale lost")) else 1
