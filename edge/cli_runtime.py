"""CLI: ``tactile-force run --scene FILE``, ``tactile-force scene show FILE``, ``tactile-force demo``."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .errors import SourceError
from .reading import Flags, ForceReading


# -- scene show ---------------------------------------------------------------------------
def configure_scene(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True)
    show = sub.add_parser("show", help="print the stages the scene will run (opens no device, loads no model)")
    show.add_argument("file", help="scene TOML file")


def main_scene(args: argparse.Namespace) -> int:
    from .scene import describe_scene, load_scene

    print("\n".join(describe_scene(load_scene(args.file))))
    return 0


# -- run ----------------------------------------------------------------------------------
def configure_run(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True, help="scene TOML file (see docs/runtime.md and edge/scenes/)")
    p.add_argument("--max-frames", type=int, default=None, help="stop after this many readings (default: scene / until sources end)")


def _summary_lines(stats, runtime) -> list[str]:
    lat = stats.latency_ms
    lines = [f"readings {stats.readings}: processed {stats.processed}, CNN {stats.inferred}, no_contact {stats.no_contact}, "
             f"stale {stats.stale}, late {stats.late}, invalid {stats.invalid}, source errors {stats.source_errors}"]
    lines.append("latency ms (p50 / p99): " + ", ".join(
        f"{k} {v['p50']:.2f}/{v['p99']:.2f}" for k, v in lat.items() if not math.isnan(v["p50"])))
    for s in runtime.sensors:
        st = s.source.stats
        lines.append(f"sensor {s.name}: frames {st.frames}, dropped {st.dropped}, corrupt {st.corrupt}"
                     + (f", ERROR {s.error}" if s.error else ""))
    return lines


def main_run(args: argparse.Namespace) -> int:
    from .outputs import StdoutWriter
    from .scene import build_scene, load_scene

    scene = load_scene(args.scene)
    built = build_scene(scene)
    for n in built.notes:
        print(f"note: {n}", file=sys.stderr)
    rt = built.runtime
    if not built.sinks:
        built.sinks.append(StdoutWriter(live=True, stream=sys.stderr, p99_ms=lambda: rt.latency()["total"]["p99"], every=4))
    limit = args.max_frames if args.max_frames is not None else (scene.max_frames or None)
    try:
        stats = rt.run(built.sinks, max_frames=limit)
    finally:
        built.close()
    print("\n".join(_summary_lines(stats, rt)), file=sys.stderr)
    return 1 if stats.source_errors == len(rt.sensors) else 0


# -- demo ---------------------------------------------------------------------------------
@dataclass
class DemoSummary:
    """What the demo measured: error of CNN readings vs ground truth, gate agreement,
    latency percentiles (ms), counts; paths of the plot, readings CSV and this JSON."""

    bundle: str
    readings: int
    contact_readings: int
    error: dict | None
    gate_agreement: float | None
    latency_ms: dict
    flags: dict
    plot: str
    readings_csv: str
    summary_json: str = ""
    notes: list[str] = field(default_factory=list)


def _plot(readings: list[ForceReading], path: Path) -> str:
    """Force over time, truth vs estimate, as PNG. matplotlib if installed, else OpenCV."""
    t = np.array([r.timestamp_ns for r in readings], np.float64)
    t = (t - t[0]) / 1e9 if t.size else t
    est = np.array([r.force_n for r in readings], np.float64)
    truth = np.array([np.nan if r.truth_n is None else r.truth_n for r in readings], np.float64)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return _plot_cv(t, est, truth, path)
    fig, ax = plt.subplots(figsize=(9, 3.6), dpi=110)
    ax.plot(t, truth, color="0.2", lw=1.5, label="ground truth")
    ax.plot(t, est, ".", ms=3, color="tab:red", label="estimate")
    ax.axhspan(1.0, 15.0, color="tab:green", alpha=0.06, label="valid range 1-15 N")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("normal force (N)")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return "matplotlib"


def _plot_cv(t: np.ndarray, est: np.ndarray, truth: np.ndarray, path: Path) -> str:
    import cv2

    w, h, m = 900, 360, 40
    img = np.full((h, w, 3), 255, np.uint8)
    fmax = max(1.0, float(np.nanmax(np.concatenate([est, truth, [1.0]]))))
    tmax = max(float(t[-1]) if t.size else 1.0, 1e-6)

    def xy(ti, fi):
        return int(m + ti / tmax * (w - 2 * m)), int(h - m - fi / fmax * (h - 2 * m))

    cv2.rectangle(img, (m, m), (w - m, h - m), (0, 0, 0), 1)
    pts = [xy(a, b) for a, b in zip(t, truth) if np.isfinite(b)]
    if len(pts) > 1:
        cv2.polylines(img, [np.array(pts, np.int32)], False, (60, 60, 60), 2)
    for a, b in zip(t, est):
        if np.isfinite(b):
            cv2.circle(img, xy(a, b), 2, (40, 40, 220), -1)
    cv2.putText(img, f"force (N), max {fmax:.1f}; gray = truth, red = estimate; {tmax:.1f} s",
                (m, m - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1)
    cv2.imwrite(str(path), img)
    return "opencv"


def run_demo(source, bundle: str | os.PathLike, out_dir: str | os.PathLike, threads: int = 1,
             echo=print, every: int = 10) -> DemoSummary:
    """Play ``source`` (a FrameSource whose frames carry truth_n) through the gate and the
    bundle, write readings.csv, force.png and summary.json to ``out_dir``."""
    from .gate import ContactGate
    from .inference import OnnxForceModel
    from .metrics import error_stats
    from .outputs import CsvWriter, format_reading
    from .runtime import ForceRuntime, RuntimeOptions, Sensor

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = OnnxForceModel(bundle, threads=threads)
    rt = ForceRuntime([Sensor("digit", source, ContactGate())], model, RuntimeOptions(report_stale=False))
    readings: list[ForceReading] = []
    csv_path = out / "readings.csv"
    with CsvWriter(csv_path) as csv_out:
        def keep(r: ForceReading) -> None:
            readings.append(r)
            if echo and (Flags.NO_CONTACT not in r.flags) and r.frame_index % every == 0:
                echo(format_reading(r))

        stats = rt.run([csv_out], on_reading=keep)
    rt.close()
    cnn = [r for r in readings if Flags.NO_CONTACT not in r.flags and math.isfinite(r.force_n)
           and r.truth_n is not None and r.truth_n > 0]
    err = None
    if cnn:
        es = error_stats([r.force_n for r in cnn], [r.truth_n for r in cnn])
        err = es.as_dict()
    with_truth = [r for r in readings if r.truth_n is not None and Flags.INVALID_INPUT not in r.flags]
    agree = None
    if with_truth:
        agree = float(np.mean([(Flags.NO_CONTACT not in r.flags) == (r.truth_n >= 1.0) for r in with_truth]))
    flag_counts: dict[str, int] = {}
    for r in readings:
        for name in r.flags.names() or ["ok"]:
            flag_counts[name] = flag_counts.get(name, 0) + 1
    plot_path = out / "force.png"
    how = _plot(readings, plot_path) if readings else "none"
    summary = DemoSummary(
        bundle=str(bundle), readings=len(readings), contact_readings=len(cnn), error=err, gate_agreement=agree,
        latency_ms=stats.latency_ms, flags=flag_counts, plot=str(plot_path), readings_csv=str(csv_path),
        notes=[f"plot drawn with {how}", "error over readings where the CNN ran and truth > 0 N",
               "gate_agreement: share of frames where gate contact == (truth >= 1 N)"],
    )
    summary.summary_json = str(out / "summary.json")
    Path(summary.summary_json).write_text(json.dumps(asdict(summary), indent=2, default=float) + "\n")
    return summary


def configure_demo(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="tactile_force_demo", help="output folder (plot, readings.csv, summary.json)")
    p.add_argument("--grasps", type=int, default=3, help="grasp sequences the virtual DIGIT plays")
    p.add_argument("--seed", type=int, default=0, help="random seed of the virtual DIGIT")
    p.add_argument("--bundle", default="default", help="model bundle (default: the embedded default model)")
    p.add_argument("--threads", type=int, default=1, help="ONNX Runtime intra-op threads")


def main_demo(args: argparse.Namespace) -> int:
    from .scene import default_bundle_path

    bundle = default_bundle_path() if args.bundle == "default" else Path(args.bundle)
    try:
        from .synthetic import VirtualDigitSource
    except ImportError as exc:
        raise SourceError(f"the demo needs tactile_force.edge.synthetic.VirtualDigitSource ({exc})") from None
    source = VirtualDigitSource(seed=args.seed, n_grasps=args.grasps, fps=60.0)
    print(f"virtual DIGIT: {args.grasps} grasps, seed {args.seed} -> bundle {bundle}")
    s = run_demo(source, bundle, args.out, threads=args.threads)
    if s.error:
        print(f"error vs truth over {s.error['n']} CNN readings: RE {s.error['re_mean']:.3f} +- {s.error['re_std']:.3f}, "
              f"MAE {s.error['mae_mean']:.3f} +- {s.error['mae_std']:.3f} N")
    if s.gate_agreement is not None:
        print(f"gate agrees with truth (contact <=> >= 1 N) on {100 * s.gate_agreement:.1f} % of frames")
    print("latency ms (p50 / p99): " + ", ".join(
        f"{k} {v['p50']:.2f}/{v['p99']:.2f}" for k, v in s.latency_ms.items() if not math.isnan(v["p50"])))
    print(f"flags: {s.flags}")
    print(f"wrote {s.plot}, {s.readings_csv}, {s.summary_json}")
    return 0
