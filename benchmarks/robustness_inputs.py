"""Cases for the robustness catalogue (benchmarks/robustness.py): inputs that a
writing verb must never destroy, labels and presses checked where they enter, calibrate-depth
radii and scales, and the smaller items (MCAP logs stopped by a signal: robustness_mcap.py).

Each case runs the user's command through the CLI in-process (or, for signals and possible
hangs, in a subprocess / a watched thread) and is classified like every other case:
``data lost`` when any input's bytes changed (or an MCAP log lost a written reading),
``hang`` when it did not answer in time, ``silent wrong`` when a bad input was taken.
"""

from __future__ import annotations

import functools
import hashlib
import io
import logging
import os
import shutil
import subprocess
import sys
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from .harness.cases import (
    Outcome,
    Verdict,
    accepted,
    cli_verdict,
    default_bundle_dir,
    make_dataset,
    refusal,
    run_cli,
    with_timeout,
    write_frame_png,
)
from .harness.paths import require_repo, shared_data
from .robustness_table import fill, rows

REPO = require_repo("the robustness suite (its workers are in tests/robustness)")
TF_CLI = REPO / "tests" / "robustness" / "tf_cli.py"
SHARED = shared_data()
HANG_S = 20.0


def digest(p: Path) -> dict[str, str] | str | None:
    """sha256 of a file, {relative path: sha256} of a folder, None when absent."""
    if p.is_dir():
        return {str(q.relative_to(p)): hashlib.sha256(q.read_bytes()).hexdigest()
                for q in sorted(p.rglob("*")) if q.is_file()}
    if p.is_file():
        return hashlib.sha256(p.read_bytes()).hexdigest()
    return None


def guarded(argv: list[str], watched: list[Path], should_fail: bool, names: tuple[str, ...] = (),
            timeout_s: float = 180.0, want_rc: set[int] | None = None) -> Verdict:
    """``tactile-force ARGV`` in-process; DATA_LOST when a watched input changed. ``want_rc``:
    the exit codes expected (default: 2 when it should fail, else 0)."""
    before = {p: digest(p) for p in watched}
    want = want_rc if want_rc is not None else {2} if should_fail else {0}
    v = with_timeout(lambda: cli_verdict(argv, want, should_fail, names), timeout_s)
    changed = [str(p) for p in watched if digest(p) != before[p]]
    if changed:
        return Verdict(Outcome.DATA_LOST, f"{' '.join(argv)}: input changed: {changed}")
    return v


def _unblock(fifo: Path) -> None:
    """Release a reader blocked opening ``fifo`` (a hung case must not keep its thread)."""
    try:
        fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        os.close(fd)
    except OSError:
        pass


def presses_folder(dest: Path) -> Path:
    """The 11 real AUROVA presses (or 11 synthetic ones when the shared data is absent)."""
    src = SHARED / "aurova_digit_grasp"
    if src.is_dir():
        return Path(shutil.copytree(src, dest))
    return make_dataset(dest, n=11, forces=[1.0 + i for i in range(11)])


def tiny_checkpoint(dest: Path) -> Path:
    import torch
    from tactile_force.export import ModelSpec, build_model
    from tactile_force.export.checkpoint import save_checkpoint

    torch.manual_seed(0)
    dest.parent.mkdir(parents=True, exist_ok=True)
    return save_checkpoint(dest, build_model("rgbmod", 0.125), ModelSpec("rgbmod", 0.125, 1 / 8))


# ================================================================== inputs never destroyed
def inputs_cases(folder: Path) -> list[tuple[str, Callable[[], Verdict]]]:
    """(what, probe) for every writing verb pointed at its own inputs. Each destructive case
    gets fresh copies of its inputs (a case that destroyed them must not change the next)."""
    ckpt0 = tiny_checkpoint(folder / "ckpt0" / "ckpt.pth")
    fp32_0 = folder / "fp32_0"
    rc, _, err = run_cli(["export", str(ckpt0), "--out", str(fp32_0), "--tolerance", "1e-3"])
    if rc != 0:
        raise RuntimeError(f"could not export the tiny fp32 bundle: {err[-300:]}")
    presses0 = presses_folder(folder / "presses0")
    n = iter(range(1000))

    def fresh() -> tuple[Path, Path, Path, Path, Path]:
        """(holder, source bundle in it, presses, run folder with ckpt.pth, fp32 bundle)."""
        d = folder / f"case{next(n)}"
        holder = d / "work"
        shutil.copytree(default_bundle_dir(), holder / "src")
        (holder / "notes.txt").write_text("my notes\n")
        presses = Path(shutil.copytree(presses0, d / "presses"))
        run1 = d / "run1"
        run1.mkdir()
        shutil.copy(ckpt0, run1 / "ckpt.pth")
        (run1 / "log.txt").write_text("training log\n")
        fp32 = Path(shutil.copytree(fp32_0, d / "fp32"))
        return holder, holder / "src", presses, run1, fp32

    def calib(out: Callable[[Path, Path, Path], Path], force: bool, names: Callable[[Path], tuple[str, ...]]
              ) -> Verdict:
        holder, src, presses, _, _ = fresh()
        o = out(holder, src, presses)
        return guarded(["calibrate-force", str(src), "--data", str(presses), "--out", str(o)]
                       + (["--force"] if force else []), [holder, presses], True, names(o))

    def export_into_run() -> Verdict:
        _, _, _, run1, _ = fresh()
        return guarded(["export", str(run1 / "ckpt.pth"), "--out", str(run1), "--force"], [run1], True, (str(run1),))

    def quantize(inside: bool) -> Verdict:
        _, _, _, _, fp32 = fresh()
        out = fp32 / "q" if inside else fp32
        return guarded(["quantize", str(fp32), "--out", str(out), "--mode", "int8-dynamic"]
                       + ([] if inside else ["--force"]), [fp32], True, ("--out",) if inside else (str(fp32),))

    def compress_into_frames() -> Verdict:
        _, _, _, run1, _ = fresh()
        frames = make_dataset(run1.parent / "frames", n=3)
        return guarded(["compress", str(run1 / "ckpt.pth"), "--frames", str(frames), "--out", str(frames),
                        "--epochs", "1"], [frames, run1], True, (str(frames),))
    replay = make_dataset(folder / "replay", n=3)
    old_csv = folder / "yesterday.csv"
    old_csv.write_text("yesterday's readings\n")
    old_jsonl = folder / "yesterday.jsonl"
    old_jsonl.write_text("{}\n")
    old_npz = folder / "cal.npz"
    old_npz.write_bytes(b"keep")
    fifo = folder / "bg_fifo.png"
    if hasattr(os, "mkfifo"):
        os.mkfifo(fifo)

    cases: list[tuple[str, Callable[[], Verdict]]] = [
        ("calibrate-force --out <folder holding the source> --force",
         lambda: calib(lambda h, s, p: h, True, lambda o: (str(o),))),
        ("calibrate-force --out <the presses folder> --force",
         lambda: calib(lambda h, s, p: p, True, lambda o: (str(o),))),
        ("calibrate-force --out <inside the source bundle>",
         lambda: calib(lambda h, s, p: s / "cal", False, lambda o: ("--out",))),
        ("export --out <folder holding the checkpoint> --force", export_into_run),
        ("quantize B --out B --force", lambda: quantize(False)),
        ("quantize B --out B/inside", lambda: quantize(True)),
        ("compress --out <the frames folder>", compress_into_frames),
        ("write_bundle(overwrite=True) onto a folder of other files", lambda: _probe_write_bundle(folder)),
    ]
    places = {"replay": replay, "old_csv": old_csv, "old_jsonl": old_jsonl, "old_npz": old_npz,
              "gelsight": SHARED / "gelsight_mini_ball_presses.npz"}
    cases += command_cases("never_destroyed", places)
    if fifo.exists():
        cases.append(("run --background <a FIFO>", lambda: _probe_fifo_run(replay, fifo)))
    return cases


def _probe_write_bundle(folder: Path) -> Verdict:
    from tactile_force.edge.bundle.store import load_bundle, write_bundle

    mine = folder / "thesis"
    mine.mkdir(exist_ok=True)
    (mine / "thesis.tex").write_text("x")
    before = digest(mine)
    b = load_bundle(default_bundle_dir())
    try:
        write_bundle(mine, b.onnx_path.read_bytes(), b.manifest, overwrite=True)
        v = accepted(True, "replaced a folder of other files")
    except BaseException as exc:  # noqa: BLE001
        v = refusal(exc, True, names=(str(mine),))
    if digest(mine) != before:
        return Verdict(Outcome.DATA_LOST, f"write_bundle replaced {mine}")
    return v


def _probe_fifo_run(replay: Path, fifo: Path) -> Verdict:
    try:
        p = subprocess.run([sys.executable, str(TF_CLI), "run", "--source", str(replay), "--background", str(fifo),
                            "--max-frames", "2"], capture_output=True, text=True, timeout=HANG_S)
    except subprocess.TimeoutExpired:
        return Verdict(Outcome.HANG, f"run --background FIFO: no answer in {HANG_S:g} s")
    if "Traceback" in p.stderr:
        return Verdict(Outcome.TRACEBACK, p.stderr[-200:])
    if p.returncode == 2 and str(fifo) in p.stderr:
        return Verdict(Outcome.CLEAR, p.stderr.strip()[-160:])
    return Verdict(Outcome.SILENT_WRONG if p.returncode == 0 else Outcome.TRACEBACK,
                   f"exit {p.returncode}: {p.stderr[-200:]}")


# ================================================================== labels and presses
def _rewrite_labels(root: Path, fn: Callable[[float], str]) -> None:
    for f in sorted((root / "forces").iterdir()):
        first, *rest = f.read_text().splitlines()
        f.write_text("\n".join([fn(float(first)), *rest]) + "\n")


def presses_cases(folder: Path) -> list[tuple[str, Callable[[], Verdict]]]:
    bundle = str(default_bundle_dir())

    def calib(data: Path, names: tuple[str, ...]) -> Verdict:
        out = data.parent / (data.name + "_cal")
        return guarded(["calibrate-force", bundle, "--data", str(data), "--out", str(out)], [data], True, names)

    def duplicated() -> Verdict:
        data = presses_folder(folder / "dup")
        for k in (1, 2):
            for img in sorted((data / "images").glob("*.png")):
                n = int(img.stem)
                shutil.copy(img, data / "images" / f"{n + 100000 * k}.png")
                shutil.copy(data / "forces" / f"force_{n}.txt", data / "forces" / f"force_{n + 100000 * k}.txt")
        return calib(data, ("the same frame twice",))

    def dataset_refusal(name: str, make: Callable[[Path], tuple[str, ...]]) -> Verdict:
        from tactile_force.edge.data.dataset import AuthorsDataset

        data = presses_folder(folder / name)
        names = make(data)
        try:
            ds = AuthorsDataset(data)
            return accepted(True, f"read {len(ds)} samples")
        except BaseException as exc:  # noqa: BLE001
            return refusal(exc, True, names=names)

    def padded(data: Path) -> tuple[str, ...]:
        first = sorted((data / "images").glob("*.png"), key=lambda p: int(p.stem))[0]
        other = sorted((data / "images").glob("*.png"), key=lambda p: int(p.stem))[1]
        shutil.copy(other, data / "images" / f"0{first.name}")
        return (f"0{first.name}", first.name)

    def jpg(data: Path) -> tuple[str, ...]:
        import cv2

        img = cv2.imread(str(sorted((data / "images").glob("*.png"))[0]))
        cv2.imwrite(str(data / "images" / "99999.jpg"), img)
        return ("99999.jpg",)

    def comma() -> Verdict:
        data = presses_folder(folder / "comma")
        _rewrite_labels(data, lambda v: f"{v:.2f}".replace(".", ","))
        return calib(data, ("decimal comma",))

    def unit() -> Verdict:
        data = presses_folder(folder / "unit")
        _rewrite_labels(data, lambda v: f"{v:.2f} N")
        return calib(data, ("unit",))

    def times_ten() -> Verdict:
        data = presses_folder(folder / "x10")
        _rewrite_labels(data, lambda v: f"{10 * v:.4f}")
        seen: list[str] = []

        class Keep(logging.Handler):
            def emit(self, record: logging.LogRecord) -> None:
                seen.append(record.getMessage())

        log = logging.getLogger("tactile_force")
        h = Keep(logging.WARNING)
        log.addHandler(h)
        try:
            v = guarded(["calibrate-force", bundle, "--data", str(data), "--out", str(folder / "x10_cal")], [data],
                        False)
        finally:
            log.removeHandler(h)
        if v.outcome is Outcome.DATA_LOST:
            return v
        if any("unit" in m and str(data) in m for m in seen):
            return Verdict(Outcome.CLEAR, f"warned: {seen[-1][:160]}")
        return Verdict(Outcome.SILENT_WRONG, f"labels x10 taken without a warning ({v})")

    def fifo_label() -> Verdict:
        from tactile_force.edge.data.labels import read_force_file

        p = folder / "fifo_label" / "force_0.txt"
        p.parent.mkdir(parents=True, exist_ok=True)
        os.mkfifo(p)

        def read() -> Verdict:
            try:
                return accepted(True, f"read {read_force_file(p)!r} from a FIFO")
            except BaseException as exc:  # noqa: BLE001
                return refusal(exc, True, names=("force_0.txt",))

        v = with_timeout(read, HANG_S)
        if v.outcome is Outcome.HANG:
            _unblock(p)
        return v

    cases: list[tuple[str, Callable[[], Verdict]]] = [
        ("presses copied 3 times -> calibrate-force", duplicated),
        ("01500.png beside 1500.png", lambda: dataset_refusal("padded", padded)),
        ("a .jpg press among the PNGs", lambda: dataset_refusal("jpg", jpg)),
        ("labels with a decimal comma -> calibrate-force", comma),
        ("labels with a unit (1.08 N) -> calibrate-force", unit),
        ("labels x10 (wrong unit) -> calibrate-force warns", times_ten),
    ]
    if hasattr(os, "mkfifo"):
        cases.append(("a FIFO label file", fifo_label))
    return cases


# ================================================================== calibrate-depth
def depth_cases(folder: Path) -> list[tuple[str, Callable[[], Verdict]]]:
    """Every wrong radius and scale (robustness_cases.toml ``[[depth_wrong]]``) on each sensor's
    ball presses (``[[depth_set]]``), then the true ones; none when the shared data is absent."""
    sets = rows("depth_set")
    if not all((SHARED / p).exists() for d in sets for p in d["source"] if not p.startswith("--")):
        return []
    cases: list[tuple[str, Callable[[], Verdict]]] = []
    k = iter(range(1000))

    def calibrate(src: list[str], r: str, s: str, refuse: bool, names: tuple[str, ...] = ()) -> Callable[[], Verdict]:
        out = folder / f"depth_{next(k)}.npz"
        return lambda: guarded(["calibrate-depth", *src, "--ball-radius-mm", r, "--px-per-mm", s, "-o", str(out)],
                               [], refuse, names)

    for d in sets:
        src = [p if p.startswith("--") else str(SHARED / p) for p in d["source"]]
        radius, scale = str(d["radius_mm"]), str(d["px_per_mm"])
        for w in rows("depth_wrong"):
            r = w.get("radius", radius)
            s = w.get("scale", scale)
            if "scale_times" in w:
                s = str(d["px_per_mm"] * w["scale_times"])
            elif "scale_over" in w:
                s = str(d["px_per_mm"] / w["scale_over"])
            cases.append((f"{d['name']}: radius {r} mm, {s} px/mm", calibrate(src, r, s, True, (w["flag"],))))
        cases.append((f"{d['name']}: the true radius and scale (valid)", calibrate(src, radius, scale, False)))
    return cases


# ================================================================== smaller items
def _d_bundle(dest: Path) -> Path:
    """A real depth (D) bundle whose manifest records no mapping: force = mean(depth) / 51."""
    import onnx
    from onnx import TensorProto, helper
    from tactile_force.edge.bundle.manifest import InputKind, InputSpec, Manifest, ModelOutputSpec, Provenance
    from tactile_force.edge.bundle.store import write_bundle

    nodes = [helper.make_node("Cast", ["depth"], ["d"], to=TensorProto.FLOAT),
             helper.make_node("ReduceMean", ["d"], ["m"], axes=[1, 2, 3], keepdims=0),
             helper.make_node("Mul", ["m", "k"], ["f"]),
             helper.make_node("Reshape", ["f", "shape"], ["force"])]
    graph = helper.make_graph(nodes, "d_mean", [helper.make_tensor_value_info("depth", TensorProto.UINT8,
                                                                              ["N", 320, 240, 1])],
                              [helper.make_tensor_value_info("force", TensorProto.FLOAT, ["N", 1])],
                              [helper.make_tensor("k", TensorProto.FLOAT, [], [1 / 51.0]),
                               helper.make_tensor("shape", TensorProto.INT64, [2], [-1, 1])])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    buf = io.BytesIO(model.SerializeToString())
    m = Manifest(variant="d", precision="fp32",
                 inputs=[InputSpec("depth", InputKind.DEPTH, [-1, 320, 240, 1], colour_order="GRAY")],
                 output=ModelOutputSpec("force", [-1, 1]), name="d_test", provenance=Provenance(note="test graph"))
    onnx.checker.check_model(model)
    return write_bundle(dest, buf.getvalue(), m).path


def smaller_cases(folder: Path) -> list[tuple[str, Callable[[], Verdict]]]:
    import cv2

    replay = make_dataset(folder / "small_replay", n=3)
    scene = folder / "topic.toml"
    scene.write_text('[runtime]\nbundle = "default"\n[[sensor]]\nname = "digit"\nsource = "virtual"\n'
                     '[[output]]\nkind = "ros2"\ntopic = "/a//b"\n')
    vga = folder / "bg_vga.png"
    cv2.imwrite(str(vga), np.full((480, 640, 3), 90, np.uint8))

    def d_bundle() -> Verdict:
        try:
            b = _d_bundle(folder / "d_bundle")
        except ImportError as exc:
            return Verdict(Outcome.ACCEPTED, f"not run: {exc}")
        return guarded(["run", "--source", str(replay), "--bundle", str(b), "--max-frames", "2"], [], True,
                       ("--depth-mapping",))

    def topic() -> Verdict:
        v = guarded(["scene", "show", str(scene)], [], True, ("topic",))
        if v.outcome is Outcome.CLEAR and "--ros2" in v.detail:
            return Verdict(Outcome.TRACEBACK, f"message names --ros2, not the topic key: {v.detail}")
        return v

    pngs = folder / "nan_frames"
    for i in range(2):
        write_frame_png(pngs / f"{i}.png", i)
    places = {"folder": folder, "replay": replay, "vga": vga, "pngs": pngs, "bundle": default_bundle_dir()}
    return [("scene topic = '/a//b' at scene show", topic), ("D bundle with --source and no depth mapping", d_bundle),
            *command_cases("smaller", places)]


def command_cases(table: str, places: Mapping[str, object]) -> list[tuple[str, Callable[[], Verdict]]]:
    """(what, probe) of each ``[[table]]`` row of robustness_cases.toml: its command run through
    the CLI with ``places`` filled in, refused naming its ``names`` (or, with ``refuse = false``,
    accepted), its ``watched`` paths unchanged. A row that ``needs`` a path absent here is left out."""
    out: list[tuple[str, Callable[[], Verdict]]] = []
    for row in rows(table):
        if "needs" in row and not Path(fill(row["needs"], places)).exists():
            continue
        argv, names = fill(row["argv"], places), tuple(fill(row.get("names", []), places))
        watched = [Path(p) for p in fill(row.get("watched", []), places)]
        out.append((row["what"], functools.partial(guarded, argv, watched, bool(row.get("refuse", True)), names)))
    return out


def run_cases(cases: list[tuple[str, Callable[[], Verdict]]], add: Callable[[Verdict], None]) -> None:
    """Run each probe; a probe that raises is a traceback naming the case."""
    for what, probe in cases:
        try:
            v = probe()
        except BaseException as exc:  # noqa: BLE001 - classified, never propagated
            v = Verdict(Outcome.TRACEBACK, f"{type(exc).__name__}: {exc}"[:300])
        add(Verdict(v.outcome, f"{what}: {v.detail}"[:400]))
