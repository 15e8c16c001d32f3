"""Error against run time of every shipped bundle (error_vs_runtime.md, .json, .png).

    python -m benchmarks error --out DIR [--quick]

Every bundle in edge/models (found by its model.json, :func:`tactile_force.edge.scene.shipped_bundles`):

1. Error on the synthetic test split: the reference dataset's held-out test indenters
   (:func:`benchmarks.reference.heldout_test_split`, rendered alone by the virtual DIGIT,
   bit for bit the reference dataset's frames), one runtime per grasp whose contact gate
   learnt that grasp's no-contact frame (the virtual DIGIT with the grasp's LED gains), the
   bundle's own depth stage; RE and MAE as ``run`` reports them
   (:func:`tactile_force.edge.data.metrics.readings_error`).
2. Error on the real AUROVA DIGIT frames (shared data ``aurova_digit_grasp`` with the
   no-contact image ``digit_backgrounds/aurova_background_b.png``), replayed through the
   runtime as ``run`` replays a folder (:func:`benchmarks.bench.replay_error`); skipped, and
   the page says so, where the shared data is absent.
3. Total latency p50 / p99 through ``ForceRuntime`` back to back and at 60 fps, one thread,
   frames in contact (:func:`benchmarks.bench.bench_bundle`, as ``tactile-force bench``).

No torch is needed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .harness.machine import command_line, describe_machine, header

PAGE, JSON, PNG = "error_vs_runtime.md", "error_vs_runtime.json", "error_vs_runtime.png"
#: the real frames and their no-contact image, in the shared data
REAL_DATA, REAL_BACKGROUND = ("aurova_digit_grasp",), ("digit_backgrounds", "aurova_background_b.png")
FPS = 60.0


@dataclass
class Error:
    """RE and MAE (N), mean and std, over ``n`` CNN readings of ``with_truth`` frames with a
    true force; ``missed``: frames with truth >= 1 N that got no force."""

    n: int
    with_truth: int
    missed: int
    re_mean: float | None
    re_std: float | None
    mae_mean: float
    mae_std: float

    def cell(self, what: str) -> str:
        mean, std = (self.re_mean, self.re_std) if what == "re" else (self.mae_mean, self.mae_std)
        return "-" if mean is None or std is None else f"{mean:.3f} +- {std:.3f}"


@dataclass
class Row:
    """One shipped bundle: what it is, its error on each data set (None: not measured), its
    total latency (ms) back to back and at :data:`FPS`, and the process CPU share then."""

    name: str
    variant: str
    precision: str
    synthetic: Error | None
    real: Error | None
    b2b_p50: float | None
    b2b_p99: float | None
    fps_p50: float | None
    fps_p99: float | None
    fps_cpu: float | None


def _f(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def synthetic_error(bundle: Path, samples: list, threads: int = 1) -> Error | None:
    """Error of ``bundle`` on ``samples`` (:func:`benchmarks.reference.heldout_test_split`)
    through ``ForceRuntime``, one runtime per grasp (see the module doc); None: no CNN reading."""
    from dataclasses import replace

    from tactile_force.edge import ContactGate, OnnxForceModel
    from tactile_force.edge.data.metrics import readings_error
    from tactile_force.edge.reading import ForceReading
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
    from tactile_force.edge.synthetic import VirtualDigit

    from .harness.sources import ListSource
    from .reference import dataset_options

    opts = dataset_options()
    digit = VirtualDigit(replace(opts.digit, seed=opts.seed))  # the renderer the samples came from
    grasps: dict[int, list] = {}
    for s in samples:
        grasps.setdefault(int(s[3]["grasp"]), []).append(s)
    model = OnnxForceModel(bundle, threads=threads)
    readings: list[ForceReading] = []
    try:
        for members in grasps.values():
            gain = tuple(float(v) for v in members[0][3].get("led_gain") or (1.0, 1.0, 1.0))
            gate = ContactGate()
            gate.capture_background([digit.render(None, 0.0, led_gain=gain, rng=np.random.default_rng(0)).frame])
            src = ListSource([s[1] for s in members], [float(s[2]) for s in members])
            rt = ForceRuntime([Sensor("s", src, gate)], model, RuntimeOptions(threads=threads, deadline_ms=1e9),
                              owns_model=False)
            try:
                rt.run(on_reading=readings.append)
            finally:
                rt.close()
    finally:
        model.close()
    rep, with_truth, missed = readings_error(readings)
    if rep is None:
        return None
    o = rep.overall
    return Error(o.n, with_truth, missed, _f(o.re_mean), _f(o.re_std), o.mae_mean, o.mae_std)


def real_error(bundle: Path, data: Path, background: Path, threads: int = 1) -> Error | None:
    """Error of ``bundle`` on a labelled folder replayed as ``run`` replays it."""
    from .bench import replay_error

    e = replay_error(bundle, data, background, threads)
    if e is None:
        return None
    return Error(e.n, e.frames_with_truth, e.missed, e.re_mean, e.re_std, e.mae_mean, e.mae_std)


def real_data() -> tuple[Path, Path] | None:
    """(the AUROVA labelled folder, its no-contact image), or None where the shared data lacks either."""
    from tactile_force.edge.errors import TactileForceError

    from .harness.paths import shared_data

    try:
        data, bg = shared_data(*REAL_DATA), shared_data(*REAL_BACKGROUND)
    except TactileForceError:
        return None
    return (data, bg) if data.is_dir() and bg.is_file() else None


def measure(quick: bool = False, threads: int = 1, echo=print) -> tuple[list[Row], str, str]:
    """Every shipped bundle's :class:`Row`, what the synthetic data were, and what the real data
    were (or why they were skipped)."""
    from tactile_force.edge.scene import shipped_bundles

    from .bench import bench_bundle, contact_frames
    from .reference import SPLIT, heldout_test_split

    bundles = shipped_bundles()
    if not bundles:
        from .harness.paths import SetupError

        raise SetupError("no shipped bundle found in edge/models (expected <name>/model.json folders)")
    samples = heldout_test_split(48 if quick else 0)
    indenters = sorted({s[3]["indenter"] for s in samples})
    syn_what = (f"synthetic test split ({SPLIT}, held-out indenters {', '.join(indenters)}): {len(samples)} frames, "
                f"{len({s[3]['grasp'] for s in samples})} grasps")
    real = real_data()
    real_what = (f"real AUROVA DIGIT frames `{REAL_DATA[0]}` (background `{'/'.join(REAL_BACKGROUND)}`)"
                 if real else f"real AUROVA frames SKIPPED: the shared data holds no {REAL_DATA[0]} and "
                              f"{'/'.join(REAL_BACKGROUND)} here")
    pool = contact_frames()
    rows = []
    for name, path in bundles.items():
        syn = synthetic_error(path, samples, threads)
        rea = real_error(path, real[0], real[1], threads) if real else None
        lat = bench_bundle(path, pool, frames=200 if quick else 1000, threads=threads, repeats=1, fps=FPS,
                           cadence_frames=60 if quick else 300)
        c = lat.cadence
        rows.append(Row(name, lat.variant, lat.precision, syn, rea, _f(lat.total_ms.p50), _f(lat.total_ms.p99),
                        None if c is None else _f(c.total_ms.p50), None if c is None else _f(c.total_ms.p99),
                        None if c is None else c.cpu_share))
        echo(f"error: {name}: RE synthetic {syn.cell('re') if syn else '-'}, real {rea.cell('re') if rea else '-'}; "
             f"total p99 {lat.total_ms.p99:.3f} ms back to back, "
             f"{'-' if c is None else f'{c.total_ms.p99:.3f}'} ms at {FPS:g} fps")
    return rows, syn_what, real_what


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def table(rows: list[Row]) -> str:
    """The page's table, one line per bundle."""
    from .harness.stats import markdown_table

    at = f"{FPS:g} fps"
    head = ["bundle", "variant", "precision", "RE synthetic test", "MAE synthetic (N)", "readings / frames (synthetic)",
            "RE real AUROVA", "MAE real (N)", "readings / frames (real)", "b2b total p50 ms", "b2b total p99 ms",
            f"{at} total p50 ms", f"{at} total p99 ms", f"{at} CPU"]

    def counts(e: Error | None) -> str:
        return "-" if e is None else f"{e.n} / {e.with_truth}"

    body = [[r.name, r.variant, r.precision,
             r.synthetic.cell("re") if r.synthetic else "-", r.synthetic.cell("mae") if r.synthetic else "-",
             counts(r.synthetic), r.real.cell("re") if r.real else "-", r.real.cell("mae") if r.real else "-",
             counts(r.real), _ms(r.b2b_p50), _ms(r.b2b_p99), _ms(r.fps_p50), _ms(r.fps_p99),
             "-" if r.fps_cpu is None else f"{100 * r.fps_cpu:.1f} %"] for r in rows]
    return markdown_table(head, body)


NOTE = """Every shipped bundle (edge/models), measured as a user runs it: frames through
ForceRuntime (the contact gate, the bundle's own depth stage, ONNX Runtime, the judge), one
thread. RE = |f_pred - f_gt| / f_gt, MAE in N (edge/data/metrics.py), over the readings where
the network gave a force for a frame with a true force ('readings / frames'). Latency: total
(frame arrival -> reading) over frames in contact, back to back and with frames arriving at
60 fps, as `tactile-force bench` measures it; CPU = process CPU time / wall time at 60 fps.
The shipped bundles were trained on synthetic virtual DIGIT frames only; the real frames come
from another sensor unit and gel, and their figures are given as measured."""


def run(args, argv) -> int:
    """``python -m benchmarks error``: measure, write the page, its JSON and the Pareto plot."""
    from dataclasses import asdict

    from tactile_force.edge.report.host import cpu_line
    from tactile_force.edge.report.plots import ParetoPoint, error_vs_latency

    from .bench import write_json

    machine = describe_machine()
    rows, syn_what, real_what = measure(args.quick)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    pts = [ParetoPoint(r.name, math.nan if p99 is None else p99, r.synthetic.re_mean if r.synthetic else None, True,
                       r.b2b_p99 if r.fps_p99 is not None else None)
           for r in rows for p99 in [r.fps_p99 if r.fps_p99 is not None else r.b2b_p99]]
    error_vs_latency(pts, 1.0, out / PNG, title=f"{machine.cpu}, 1 thread, RE on the synthetic test split, "
                                                f"p99 at {FPS:g} fps", also="back to back")
    command = command_line(argv)
    write_json(out / JSON, {"command": command, "machine": asdict(machine), "synthetic": syn_what,
                            "real": real_what, "fps": FPS, "rows": [asdict(r) for r in rows]})
    notes = "\n".join([cpu_line(machine.cpu, machine.cores) + ".", "", f"Synthetic: {syn_what}.",
                       f"Real: {real_what}.", "", NOTE])
    text = header("Error against run time", command, machine, notes) + "\n".join([
        table(rows), "", f"![error against p99 at {FPS:g} fps]({PNG})", ""])
    (out / PAGE).write_text(text)
    print(f"wrote {out / PAGE}, {out / JSON}, {out / PNG}")
    return 0
