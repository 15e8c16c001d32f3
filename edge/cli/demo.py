"""``tactile-force demo``: virtual DIGIT grasps through the embedded default model; readings
against truth, RE/MAE, per-stage latency and a force-over-time plot (no hardware)."""

from __future__ import annotations

import argparse
import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..data.metrics import cnn_readings
from ..errors import SceneError, SourceError
from ..limits import GRASPS, SEED, THREADS
from ..reading import Flags, ForceReading
from .args import within
from .replay_report import PLOT_NAME, plot_force


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


def run_demo(source, bundle: str | os.PathLike, out_dir: str | os.PathLike, threads: int = 1,
             echo=print, every: int = 10, publish_as: str | os.PathLike | None = None) -> DemoSummary:
    """Play ``source`` (a FrameSource whose frames carry truth_n) through the gate and the
    bundle, write readings.csv, force_vs_time.png (:data:`PLOT_NAME`) and summary.json to ``out_dir``
    (the summary names the files under ``publish_as`` when ``out_dir`` is a staging folder moved there)."""
    from ..data.metrics import error_stats
    from ..gate.contact_gate import ContactGate
    from ..model.onnx_model import OnnxForceModel
    from ..outputs import CsvWriter, format_reading
    from ..runtime import ForceRuntime, RuntimeOptions, Sensor

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = OnnxForceModel(bundle, threads=threads)
    rt = ForceRuntime([Sensor("digit", source, ContactGate())], model, RuntimeOptions(report_stale=False))
    readings: list[ForceReading] = []
    csv_path = out / "readings.csv"
    try:
        with CsvWriter(csv_path) as csv_out:
            def keep(r: ForceReading) -> None:
                readings.append(r)
                if echo and (Flags.NO_CONTACT not in r.flags) and r.frame_index % every == 0:
                    echo(format_reading(r))

            stats = rt.run([csv_out], on_reading=keep)
    finally:  # also on Ctrl-C: the source's render thread must end before the interpreter does
        rt.close()
    cnn = cnn_readings(readings)
    err = None
    if cnn:
        es = error_stats([r.force_n for r in cnn], [float(r.truth_n or 0.0) for r in cnn])
        err = es.as_dict()
    with_truth = [r for r in readings if r.truth_n is not None and Flags.INVALID_INPUT not in r.flags]
    agree = None
    if with_truth:
        agree = float(np.mean([(Flags.NO_CONTACT not in r.flags) == ((r.truth_n or 0.0) >= 1.0) for r in with_truth]))
    flag_counts: dict[str, int] = {}
    for r in readings:
        for name in r.flags.names() or ["ok"]:
            flag_counts[name] = flag_counts.get(name, 0) + 1
    plot_path = out / PLOT_NAME
    how = plot_force(readings, plot_path) if readings else "none"
    final = Path(publish_as) if publish_as is not None else out
    summary = DemoSummary(
        bundle=str(bundle), readings=len(readings), contact_readings=len(cnn), error=err, gate_agreement=agree,
        latency_ms=stats.latency_ms, flags=flag_counts, plot=str(final / PLOT_NAME),
        readings_csv=str(final / "readings.csv"),
        notes=[f"plot drawn with {how}", "error over readings where the CNN ran and truth > 0 N",
               "gate_agreement: share of frames where gate contact == (truth >= 1 N)"],
    )
    summary.summary_json = str(final / "summary.json")
    (out / "summary.json").write_text(json.dumps(asdict(summary), indent=2, default=float) + "\n")
    return summary


def configure(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="tactile_force_demo",
                   help=f"output folder, relative to the working directory ({PLOT_NAME}, readings.csv, summary.json)")
    p.add_argument("--grasps", type=within(int, GRASPS), default=3,
                   help="grasp sequences the virtual DIGIT plays (>= 1)")
    p.add_argument("--seed", type=within(int, SEED), default=0, help="random seed of the virtual DIGIT")
    p.add_argument("--bundle", default="default", help="model bundle (default: the embedded default model)")
    p.add_argument("--threads", type=within(int, THREADS), default=1, help="ONNX Runtime intra-op threads (>= 1)")
    p.add_argument("--force", action="store_true", help="replace --out when it holds an earlier demo's result")


def main(args: argparse.Namespace) -> int:
    from ..scene import default_bundle_path

    bundle = default_bundle_path() if args.bundle == "default" else Path(args.bundle)
    if not (bundle / "model.json").is_file():
        raise SceneError(f"--bundle {bundle}: not a bundle folder (expected model.json in it)")
    from ..files.guard import OutputKind, check_output

    out = Path(args.out).absolute()
    # a new or empty folder, or (--force) an earlier demo's result holding nothing else; never the bundle
    check_output(out, [("--bundle", bundle)], force=getattr(args, "force", False), kind=OutputKind.FOLDER)
    try:
        from ..synthetic import VirtualDigitSource
    except ImportError as exc:
        raise SourceError(f"the demo needs tactile_force.edge.synthetic.VirtualDigitSource ({exc})") from None
    source = VirtualDigitSource(seed=args.seed, n_grasps=args.grasps, fps=60.0)
    from ..report.host import cpu_line

    print(f"virtual DIGIT: {args.grasps} grasps, seed {args.seed} -> bundle {bundle}")
    print(cpu_line())  # the host the latency below was measured on
    from ..files.atomic import staged_folder

    # claimed and judged (a link, a mount point, a read-only or unwritable parent) before the run
    with staged_folder(out, "demo", force=getattr(args, "force", False), inputs=[("--bundle", bundle)]) as tmp:
        s = run_demo(source, bundle, tmp, threads=args.threads, publish_as=out)
    if s.error:
        print(f"error vs truth over {s.error['n']} CNN readings: "
              f"RE {s.error['re_mean']:.3f} +- {s.error['re_std']:.3f}, "
              f"MAE {s.error['mae_mean']:.3f} +- {s.error['mae_std']:.3f} N")
    if s.gate_agreement is not None:
        print(f"gate agrees with truth (contact <=> >= 1 N) on {100 * s.gate_agreement:.1f} % of frames")
    print("latency ms (p50 / p99): " + ", ".join(
        f"{k} {v['p50']:.2f}/{v['p99']:.2f}" for k, v in s.latency_ms.items() if not math.isnan(v["p50"])))
    print("  (the virtual DIGIT renders its frames on this same CPU while the runtime reads them, so these "
          "figures include that contention; 'tactile-force bench' measures the runtime alone on in-memory frames)")
    print(f"flags: {s.flags}")
    print(f"wrote {s.plot}, {s.readings_csv}, {s.summary_json}")
    return 0
