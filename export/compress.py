"""Distil a trained model into compact RGBmod students and keep the best one within a latency budget.

    compress_model(CompressOptions(teacher="model.pth", frames=["frames/"], out="compressed"))

Steps (``tactile-force compress``):

1. read the UNLABELLED frames (plain image folders, videos, the authors' layout, ``record``
   output) and, if given, labelled frames (authors' layout);
2. run the teacher (a checkpoint, authors' format or ours, or an fp32 bundle through ONNX
   Runtime) once on all of them; its outputs are cached in ``OUT/work`` under a key made of
   the teacher's sha256 and the frames' content;
3. train each student of the ladder (width x input scale 1/k x residual blocks per stage:
   narrower, smaller-input and fewer-blocks students) on the teacher's outputs with
   sensor-variability augmentation (:mod:`.training`, the same loop as the reference recipe);
   half of the labelled frames (when there are >= 10) are mixed in with their labels, the
   other half are kept for evaluation. Each finished student is saved in ``OUT/work``
   (checkpoint + record): Ctrl-C keeps them and a rerun resumes with the next student;
4. export each student, quantize it to int8 (static, calibrated on the same unlabelled
   frames it was distilled on), measure its p99 on this host through the runtime's model
   (:class:`OnnxForceModel`, batch 2, one thread), and its error against the teacher on
   held-out unlabelled frames and against the held-out labels;
5. time every student in round-robin blocks (p99 = the median of its block p99s), order them by
   that p99 and record what each step down costs in error (:func:`error_steps`: RE vs the
   teacher and vs the labels, against the next costlier student or the teacher), then write
   the most accurate student (vs the teacher) whose p99 fits the budget and whose error vs
   the teacher is within ``max_vs_teacher_re`` to ``OUT/bundle``; none: no bundle (the CLI
   exits 1 with the table). Its manifest records the teacher, both errors, the latency, the
   host and ``data_stats`` of the frames compress saw (the runtime's honesty checks).

Deterministic for a seed on a given machine; CPU only.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import os
import platform
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np
from tactile_force.edge.bundle.data_stats import DataStats
from tactile_force.edge.bundle.manifest import ErrorFigures, ErrorReport
from tactile_force.edge.bundle.store import Bundle, load_bundle, write_bundle
from tactile_force.edge.data.dataset import AuthorsDataset, read_image
from tactile_force.edge.data.metrics import error_stats
from tactile_force.edge.errors import DatasetError, TactileForceError
from tactile_force.edge.fitting.data_stats import frames_data_stats
from tactile_force.edge.fitting.interval import fit_interval
from tactile_force.edge.frames import FRAME_SHAPE

from .calibration import CalibrationData
from .checkpoint import model_from_checkpoint, save_checkpoint
from .onnx_export import ExportOptions, export_bundle, ort_session, run_ort
from .preprocess import ForceNet
from .quantize import QuantizeOptions, quantize_bundle
from .training import Augment, Frames, TrainOptions, predict, preprocess, train_network
from .zoo import RESNET18_BLOCKS, ModelSpec, blocks_tag, check_blocks

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".webm")


class CompressError(TactileForceError, ValueError):
    """Bad input to compress (frames, teacher, options); nothing was written."""


@dataclass(frozen=True)
class Rung:
    """One student of the ladder: RGBmod at width multiplier ``width``, input scale 1/``k``
    and ``blocks`` residual blocks per stage (ResNet-18's (2, 2, 2, 2) unless fewer)."""

    width: float
    k: int
    blocks: tuple[int, int, int, int] = RESNET18_BLOCKS

    @property
    def name(self) -> str:
        return f"rgbmod-w{self.width:g}-s{self.k}{blocks_tag(self.blocks)}"

    @property
    def spec(self) -> ModelSpec:
        return ModelSpec("rgbmod", self.width, 1.0 / self.k, self.blocks)

    @property
    def text(self) -> str:
        """The rung as ``--ladder`` writes it: '0.25x4', '0.25x4b1111'."""
        return f"{self.width:g}x{self.k}{blocks_tag(self.blocks).replace('-b', 'b')}"


#: The default ladder, cheapest first (0.005 to 0.06 GMAC a frame): narrower, smaller-input
#: and fewer-blocks students (one block per stage: about half the layers of ResNet-18's two).
DEFAULT_LADDER: tuple[Rung, ...] = (Rung(0.125, 8), Rung(0.25, 4, (1, 1, 1, 1)), Rung(0.25, 4),
                                    Rung(0.5, 4, (1, 1, 1, 1)), Rung(0.5, 4), Rung(0.25, 2))


def parse_ladder(text: str) -> tuple[Rung, ...]:
    """'0.25x4,0.5x4b1111' -> rungs (width x k, optionally b + four blocks-per-stage digits)."""
    rungs = []
    for part in (p.strip() for p in text.split(",") if p.strip()):
        try:
            head, _, tail = part.lower().partition("b")
            w, k = head.split("x")
            blocks = tuple(int(c) for c in tail) if tail else RESNET18_BLOCKS
            rungs.append(Rung(float(w), int(k), check_blocks(blocks)))
        except (ValueError, TactileForceError):
            raise CompressError(f"--ladder {part!r}: expected WIDTHxK or WIDTHxKbNNNN, e.g. 0.25x4 (width 0.25, "
                                "input 1/4) or 0.25x4b1111 (the same with one residual block per stage)") from None
    if not rungs:
        raise CompressError("--ladder: no students given")
    return tuple(rungs)


@dataclass
class CompressOptions:
    """What to compress and how.

    teacher: checkpoint (.pth / .pth.tar) or fp32 bundle folder (RGBmod). frames: unlabelled
    inputs. labels: an authors'-layout folder of labelled frames. out: output folder.
    budget_ms: p99 budget per batch-2 inference on this host. epochs, lr, batch: training.
    max_frames: unlabelled frames used at most (evenly subsampled). val_share: held-out
    share of the unlabelled frames. latency_runs: timed batch-2 calls per block;
    latency_blocks: blocks per student, timed round-robin over all students once they are
    trained; a student's p99 is the median of its block p99s (one noisy block cannot flip
    the choice). max_vs_teacher_re: the largest RE against the teacher (held-out unlabelled
    frames) a student may have to be written as the result (default 0.25; the distillation
    study's students are at 0.01-0.07): a worse student is not a compressed teacher.
    on_student: called with each student's record when it is trained (tests use it).
    background: a no-contact frame (or its image path) of the sensor the frames come from:
    with it the bundle's ``data_stats`` also record contact sizes (the contact-size check);
    without it only the frames' colours (the out-of-distribution check), with a warning.
    """

    teacher: str | os.PathLike
    frames: list[str | os.PathLike]
    out: str | os.PathLike
    labels: str | os.PathLike | None = None
    budget_ms: float = 1.0
    seed: int = 0
    ladder: tuple[Rung, ...] = DEFAULT_LADDER
    epochs: int = 30
    lr: float = 1e-3
    batch: int = 64
    augment: Augment | None = field(default_factory=Augment)
    max_frames: int = 6000
    val_share: float = 0.15
    threads: int | None = None
    latency_runs: int = 200
    latency_blocks: int = 5
    max_vs_teacher_re: float = 0.25
    calibration_frames: int = 200
    show_progress: bool = False
    on_student: Callable[[dict], None] | None = None
    background: str | os.PathLike | np.ndarray | None = None


@dataclass
class CompressResult:
    """The written bundle, the chosen student's record and every student's record."""

    bundle: Bundle | None
    chosen: dict | None
    students: list[dict]
    summary_path: Path


# ----------------------------------------------------------------------------- frames

def _check(img: np.ndarray | None, where: str) -> np.ndarray:
    if img is None:
        raise CompressError(f"{where}: cannot read the image (unreadable or not an image)")
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    if img.shape != FRAME_SHAPE or img.dtype != np.uint8:
        hint = " (it looks transposed: rotate it to portrait)" if img.shape[:2] == FRAME_SHAPE[1::-1] else ""
        raise CompressError(f"{where}: frame is {img.shape} {img.dtype}; expected {FRAME_SHAPE} uint8 BGR "
                            f"(DIGIT portrait, 320 rows x 240 columns){hint}")
    return img


def read_frames(paths: list[str | os.PathLike], limit: int | None = None) -> tuple[np.ndarray, str]:
    """Unlabelled frames (N,320,240,3) uint8 BGR from folders, videos or authors'-layout datasets."""
    frames: list[np.ndarray] = []
    parts = []
    for raw in paths:
        p = Path(raw)
        before = len(frames)
        if p.is_dir() and (p / "images").is_dir():
            try:  # frames judged at open and read as they are (never converted), as every labelled-data reader
                ds = AuthorsDataset(p)
                frames += [read_image(ds.image_path(n), shape=ds.shape) for n in ds.ids]
            except DatasetError as exc:
                raise CompressError(f"--frames: {exc}") from None
        elif p.is_dir():
            files = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES and f.is_file())
            if not files:
                raise CompressError(f"--frames {p}: no images ({', '.join(IMAGE_SUFFIXES)}) in this folder")
            frames += [_check(cv2.imread(str(f)), str(f)) for f in files]
        elif p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES:
            cap = cv2.VideoCapture(str(p))
            try:
                while True:
                    ok, img = cap.read()
                    if not ok:
                        break
                    frames.append(_check(img, f"{p} frame {len(frames) - before}"))
            finally:
                cap.release()
            if len(frames) == before:
                raise CompressError(f"--frames {p}: no frames could be decoded from this video")
        elif not p.exists():
            raise CompressError(f"--frames {p}: not found")
        else:
            raise CompressError(f"--frames {p}: expected a folder of images, an authors'-layout dataset or a video "
                                f"({', '.join(VIDEO_SUFFIXES)})")
        parts.append(f"{p} ({len(frames) - before})")
    arr = np.stack(frames) if frames else np.empty((0, *FRAME_SHAPE), np.uint8)
    if limit is not None and len(arr) > limit:
        arr = arr[np.linspace(0, len(arr) - 1, limit).round().astype(int)]
    return arr, ", ".join(parts)


def read_labels(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Labelled frames and forces (N) from an authors'-layout folder."""
    try:
        ds = AuthorsDataset(path)
        samples = [ds.load(n) for n in ds.ids]
    except DatasetError as exc:
        raise CompressError(f"--labels: {exc}") from None
    frames = np.stack([_check(s.frame, str(ds.image_path(s.id))) for s in samples])
    return frames, np.array([s.force_n for s in samples], np.float64)


# ----------------------------------------------------------------------------- teacher

@dataclass
class Teacher:
    """A teacher model: kind ('checkpoint' | 'bundle'), its file's sha256, a predict function."""

    source: str
    kind: str
    sha256: str
    description: str
    predict: Callable[[np.ndarray], np.ndarray]


def load_teacher(path: str | os.PathLike) -> Teacher:
    """A checkpoint (authors' or ours, RGBmod) or an fp32 RGBmod bundle, as a batch predictor."""
    p = Path(path)
    if p.is_dir() or p.suffix in (".onnx", ".json"):
        b = load_bundle(p)
        if b.manifest.variant.value != "rgbmod":
            raise CompressError(f"teacher {p}: a {b.manifest.variant.value} bundle; compress distils RGBmod "
                                "teachers (students read RGB frames only)")
        session = ort_session(b.onnx_path.read_bytes(), threads=max(1, os.cpu_count() or 1))

        def run_bundle(frames: np.ndarray) -> np.ndarray:
            ids = [str(i) for i in range(len(frames))]
            data = CalibrationData({b.manifest.inputs[0].name: frames}, None, "frames", ids)
            return run_ort(session, data.for_manifest(b.manifest), batch_size=16)

        return Teacher(str(p), "bundle", b.manifest.sha256, f"bundle {b.name} ({b.manifest.precision.value})",
                       run_bundle)
    if not p.is_file():
        raise CompressError(f"teacher {p}: not found (expected a .pth checkpoint or a bundle folder)")
    model, spec, _ = model_from_checkpoint(p, None)
    if spec.variant != "rgbmod":
        raise CompressError(f"teacher {p}: a {spec.variant} checkpoint; compress distils RGBmod teachers")
    net = ForceNet(model, spec).eval()
    sha = hashlib.sha256(p.read_bytes()).hexdigest()

    def run_checkpoint(frames: np.ndarray) -> np.ndarray:
        return predict(model, preprocess(net, {"rgb": frames}, chunk=64), batch=64).astype(np.float64)

    return Teacher(str(p), "checkpoint", sha, f"checkpoint {p.name} (rgbmod w{spec.width:g} "
                   f"input 1/{round(1 / spec.input_scale)})", run_checkpoint)


def frames_digest(*arrays: np.ndarray) -> str:
    """sha256 of the frames' bytes (the teacher-output cache key)."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(str(a.shape).encode())
        h.update(np.ascontiguousarray(a).data)
    return h.hexdigest()


def teacher_outputs(teacher: Teacher, frames: np.ndarray, work: Path, key: str, show: bool) -> np.ndarray:
    """Teacher forces (N,) on ``frames``, computed once and cached in ``work`` under ``key``."""
    cache = work / f"teacher-{key[:24]}.npy"
    if cache.is_file():
        out = np.load(cache)
        if out.shape == (len(frames),):
            return out
    chunk = 64
    parts = []
    from tqdm import tqdm

    for i in tqdm(range(0, len(frames), chunk), desc="teacher", unit="batch", disable=not show, leave=False):
        parts.append(teacher.predict(frames[i:i + chunk]))
    out = np.concatenate(parts) if parts else np.empty(0)
    if not np.all(np.isfinite(out)):
        raise CompressError(f"teacher {teacher.source}: gives non-finite forces on some frames")
    tmp = cache.with_name(cache.name + ".tmp.npy")
    np.save(tmp, out)
    os.replace(tmp, cache)
    return out


# ----------------------------------------------------------------------------- the ladder

def host_description() -> str:
    """CPU model, logical cores and OS of this host (recorded with latency figures)."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} logical cores, {platform.system()} {platform.release()}"


def _figures(pred: np.ndarray, ref: np.ndarray) -> dict:
    return error_stats(pred, ref).as_dict()  # the fields of manifest.ErrorFigures


def _write_json(path: Path, obj: object) -> None:
    from tactile_force.edge.files.atomic import staged_file

    with staged_file(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2, default=float))


def compress_model(o: CompressOptions) -> CompressResult:
    """Run the whole compression (see the module docstring); resumes from ``o.out/work``."""
    if not o.ladder:
        raise CompressError("ladder: no students given")
    if not (math.isfinite(o.budget_ms) and o.budget_ms > 0):
        raise CompressError(f"--budget-ms {o.budget_ms}: expected a positive number of milliseconds")
    if not (o.max_vs_teacher_re > 0) or math.isnan(o.max_vs_teacher_re):
        raise CompressError(f"--max-vs-teacher-re {o.max_vs_teacher_re}: expected a number > 0 (RE against the "
                            "teacher, e.g. 0.25)")
    if o.latency_runs < 1 or o.latency_blocks < 1:
        raise CompressError(f"latency_runs {o.latency_runs}, latency_blocks {o.latency_blocks}: expected >= 1")
    if not 0 < o.val_share < 0.5:
        raise CompressError(f"val_share {o.val_share}: expected 0 < share < 0.5")
    for r in o.ladder:
        if not (0 < r.width <= 4) or r.k < 1 or FRAME_SHAPE[0] % r.k or FRAME_SHAPE[1] % r.k:
            raise CompressError(f"ladder {r.width:g}x{r.k}: expected 0 < width <= 4 and k dividing 320 and 240")
    # the training options are checked here too (threads), before any work
    topt = TrainOptions(epochs=o.epochs, lr=o.lr, batch=o.batch, seed=o.seed, threads=o.threads, augment=o.augment)
    out = Path(o.out)
    work = out / "work"
    show = o.show_progress
    teacher = load_teacher(o.teacher)
    frames, frames_desc = read_frames(list(o.frames), o.max_frames)
    if len(frames) < 20:
        raise CompressError(f"--frames: only {len(frames)} frame(s); at least 20 are needed (a few thousand covering "
                            "light to firm presses is better)")
    lab_frames, lab_forces = (read_labels(o.labels) if o.labels is not None
                              else (np.empty((0, *FRAME_SHAPE), np.uint8), np.empty(0)))
    # What the student sees, for the runtime's honesty checks (out-of-distribution, contact size).
    data_stats = frames_data_stats(list(frames) + list(lab_frames), o.background,
                                   f"{len(frames) + len(lab_frames)} compress frames ({frames_desc})", "compress")
    work.mkdir(parents=True, exist_ok=True)
    key = hashlib.sha256((teacher.sha256 + frames_digest(frames)).encode()).hexdigest()
    t_frames = teacher_outputs(teacher, frames, work, key, show)

    rng = np.random.default_rng(o.seed)
    order = rng.permutation(len(frames))
    n_val = max(2, round(o.val_share * len(frames)))
    val_idx, tr_idx = np.sort(order[:n_val]), np.sort(order[n_val:])
    lab_order = rng.permutation(len(lab_forces))
    if len(lab_forces) >= 10:
        lab_tr, lab_ev = np.sort(lab_order[: len(lab_order) // 2]), np.sort(lab_order[len(lab_order) // 2:])
    else:
        lab_tr, lab_ev = np.empty(0, int), np.sort(lab_order)
    train = Frames({"rgb": np.concatenate([frames[tr_idx], lab_frames[lab_tr]])},
                   np.concatenate([t_frames[tr_idx], lab_forces[lab_tr]]).astype(np.float32))
    val = Frames({"rgb": frames[val_idx]}, t_frames[val_idx])
    lab_key = frames_digest(lab_frames, lab_forces) if len(lab_forces) else ""
    run_key = hashlib.sha256(json.dumps([key, lab_key, o.seed, o.val_share, asdict(topt)],
                                        default=str).encode()).hexdigest()[:16]
    calib = CalibrationData({"rgb": train.inputs["rgb"][
        np.linspace(0, len(train) - 1, min(o.calibration_frames, len(train))).round().astype(int)]},
        None, f"{len(train)} distillation frames ({frames_desc})", [])
    calib.ids = [str(i) for i in range(len(calib.inputs["rgb"]))]
    val_data = CalibrationData({"rgb": val.inputs["rgb"]}, None, "held-out unlabelled frames",
                               [str(i) for i in range(len(val))])
    lab_ev_data = (CalibrationData({"rgb": lab_frames[lab_ev]}, lab_forces[lab_ev], f"{o.labels} (held-out half)",
                                   [str(i) for i in lab_ev]) if len(lab_ev) else None)

    from tqdm import tqdm

    records: list[dict] = []
    for rung in tqdm(o.ladder, desc="students", unit="student", disable=not show):
        sdir = work / f"{rung.name}-{run_key}"
        rec_path = sdir / "record.json"
        if rec_path.is_file():
            rec = json.loads(rec_path.read_text())
            rec["resumed"] = True
        else:
            sdir.mkdir(parents=True, exist_ok=True)
            res = train_network(rung.spec, train, val, topt, show_progress=show, desc=rung.name)
            save_checkpoint(sdir / "model.pth", res.model, rung.spec,
                            extra={"trained_on": f"distilled from {teacher.description} on {frames_desc}"})
            rec = {"name": rung.name, "width": rung.width, "k": rung.k, "blocks": list(rung.blocks),
                   "best_epoch": res.best_epoch,
                   "train_seconds": round(res.seconds, 1), "epochs": o.epochs, "resumed": False}
            _write_json(rec_path, rec)
        if "vs_teacher" not in rec:
            rec.update(_finish_student(sdir, rung, teacher, calib, val_data, val.targets, lab_ev_data, o))
            _write_json(rec_path, {k: v for k, v in rec.items() if k != "resumed"})
        records.append(rec)
        if o.on_student is not None:
            o.on_student(rec)

    time_students(records, o.latency_runs, o.latency_blocks)
    error_steps(records)
    fits = [r for r in records if r["p99_ms"] <= o.budget_ms]
    for rec in records:
        rec["within_error_limit"] = bool(rec["vs_teacher"]["re_mean"] <= o.max_vs_teacher_re)
    good = [r for r in fits if r["within_error_limit"]]
    chosen = min(good, key=lambda r: r["vs_teacher"]["re_mean"]) if good else None
    bundle = None
    if chosen is not None:
        bundle = _write_final(out / "bundle", chosen, teacher, frames_desc, len(frames), o, records, data_stats)
    elif (out / "bundle" / "model.json").is_file():  # an earlier run's choice must not look like this run's
        shutil.rmtree(out / "bundle")
    summary = out / "compress.json"
    _write_json(summary, {"teacher": {"source": teacher.source, "kind": teacher.kind, "sha256": teacher.sha256},
                          "frames": frames_desc, "labels": str(o.labels) if o.labels else None,
                          "budget_ms": o.budget_ms, "max_vs_teacher_re": o.max_vs_teacher_re,
                          "seed": o.seed, "host": host_description(),
                          "chosen": chosen["name"] if chosen else None, "students": records})
    return CompressResult(bundle, chosen, records, summary)


def _finish_student(sdir: Path, rung: Rung, teacher: Teacher, calib: CalibrationData, val_data: CalibrationData,
                    val_teacher: np.ndarray, lab_ev: CalibrationData | None, o: CompressOptions) -> dict:
    """Export, int8-quantize, evaluate and time one trained student."""
    fp32 = export_bundle(sdir / "model.pth", sdir / "fp32", ExportOptions(
        parity_data=val_data.subset(16), name=f"{rung.name}-fp32", overwrite=True,
        trained_on=f"distilled from {teacher.description}"))
    int8 = quantize_bundle(fp32, sdir / "int8", QuantizeOptions(mode="int8-static", name=f"{rung.name}-int8",
                                                                overwrite=True), calibration=calib, eval_data=val_data)
    sess = ort_session(int8.onnx_path.read_bytes(), threads=max(1, os.cpu_count() or 1))
    m = int8.manifest  # compact students read frames reduced as the runtime reduces them
    rec: dict = {"vs_teacher": _figures(run_ort(sess, val_data.for_manifest(m)), val_teacher)}
    if lab_ev is not None and lab_ev.forces is not None:
        pred = run_ort(sess, lab_ev.for_manifest(m))
        rec["vs_labels"] = _figures(pred, lab_ev.forces)
        # the held-out labelled frames: the final bundle's interval is fitted on them (_write_final)
        rec["labels_pred_n"] = [float(v) for v in pred]
        rec["labels_truth_n"] = [float(v) for v in lab_ev.forces]
        rec["teacher_vs_labels"] = _figures(teacher.predict(lab_ev.inputs["rgb"]), lab_ev.forces)
    rec["gmacs"] = int8.manifest.architecture.gmacs
    rec["bundle"] = str(sdir / "int8")
    return rec


def time_students(records: list[dict], runs: int, blocks: int) -> None:
    """Set each record's ``p99_ms`` to the median of ``blocks`` block p99s (ms) of a batch-2
    predict (``runs`` calls a block, one thread), the blocks taken round-robin over the
    students so that machine noise falls on all of them alike; ``p99_blocks_ms`` keeps them."""
    from tactile_force.edge.model.ladder import measure_p99_ms
    from tactile_force.edge.model.onnx_model import OnnxForceModel

    models = [OnnxForceModel(r["bundle"], threads=1) for r in records]
    try:
        per: list[list[float]] = [[] for _ in records]
        for _ in range(blocks):
            for k, m in enumerate(models):
                per[k].append(measure_p99_ms(m, runs=runs))
    finally:
        for m in models:
            m.close()
    for r, p in zip(records, per):
        r["p99_ms"] = float(np.median(p))
        r["p99_blocks_ms"] = [round(v, 4) for v in p]


def error_steps(records: list[dict]) -> list[dict]:
    """What each step down the ladder costs in error, cheapest last: ``records`` ordered by
    measured p99 (costliest first); each gets ``step`` = {"from": the next costlier student's
    name, or "teacher" for the costliest, "vs_teacher_re": its RE vs the teacher minus that
    one's (the teacher's own is 0), "vs_labels_re": the same against the labels (the teacher's
    RE vs the labels for the first step), or None without labels}. Returns the ordered list."""
    ordered = sorted(records, key=lambda r: -float(r["p99_ms"]))
    prev: dict | None = None
    for rec in ordered:
        vl = rec.get("vs_labels")
        if prev is None:
            base_t, base_l = 0.0, rec.get("teacher_vs_labels", {}).get("re_mean") if vl else None
        else:
            base_t, base_l = prev["vs_teacher"]["re_mean"], prev.get("vs_labels", {}).get("re_mean")
        rec["step"] = {"from": prev["name"] if prev is not None else "teacher",
                       "vs_teacher_re": float(rec["vs_teacher"]["re_mean"] - base_t),
                       "vs_labels_re": (float(vl["re_mean"] - base_l) if vl is not None and base_l is not None
                                        else None)}
        prev = rec
    return ordered


def _write_final(dest: Path, chosen: dict, teacher: Teacher, frames_desc: str, n_frames: int, o: CompressOptions,
                 records: list[dict], data_stats: DataStats) -> Bundle:
    src = load_bundle(chosen["bundle"])
    m = copy.deepcopy(src.manifest)
    m.data_stats, m.data_stats_missing = data_stats, ""
    m.name = f"{chosen['name']}-int8-distilled"
    vt = chosen["vs_teacher"]
    vl = chosen.get("vs_labels")
    m.error = ErrorReport(
        data=(f"{o.labels} (held-out half of the labelled frames)" if vl else
              f"held-out unlabelled frames ({vt['n']}) vs the teacher"),
        frames=vl["n"] if vl else vt["n"],
        vs_truth=ErrorFigures(**vl) if vl else None,
        vs_teacher=ErrorFigures(**vt))
    # every reading's error bar: split conformal on the held-out labelled frames (edge/bundle/interval.py);
    # without labels none (an interval against the teacher would not bound the true force)
    pred, truth = chosen.get("labels_pred_n"), chosen.get("labels_truth_n")
    m.interval = (fit_interval(pred, truth, model_sha256=src.manifest.sha256,
                               data=f"{o.labels} (held-out half of the labelled frames, {len(pred)})")
                  if pred and truth else None)
    m.provenance.trained_on = f"distilled from the teacher on {n_frames} unlabelled frames: {frames_desc}"
    m.provenance.teacher = {"source": teacher.source, "kind": teacher.kind, "sha256": teacher.sha256,
                            "description": teacher.description}
    m.provenance.host = host_description()
    m.provenance.extra = {"p99_ms_batch2": round(float(chosen["p99_ms"]), 4), "budget_ms": o.budget_ms,
                          "seed": o.seed, "epochs": o.epochs, "student": chosen["name"],
                          "ladder": ",".join(f"{r['name']}:{r['p99_ms']:.3f}ms" for r in records),
                          "vs_teacher_re_mean": vt["re_mean"]}
    m.provenance.note = (f"Distilled by 'tactile-force compress' ({time.strftime('%Y-%m-%d')}); "
                         "student-vs-teacher error on held-out unlabelled frames in error.vs_teacher.")
    return write_bundle(dest, src.onnx_path.read_bytes(), m, overwrite=True)


__all__ = [
    "DEFAULT_LADDER",
    "CompressError",
    "CompressOptions",
    "CompressResult",
    "Rung",
    "compress_model",
    "error_steps",
    "load_teacher",
    "parse_ladder",
    "read_frames",
]
