"""Reference models: a reproducible CPU training recipe on synthetic DIGIT frames.

Training lives outside this package; this recipe exists so that the benchmarks can
report error against run time with real trained weights, and so the embedded default
model can be rebuilt by anyone:

    python -m benchmarks.reference                     # every config in CONFIGS
    python -m benchmarks.reference --configs rgbmod-w0.25-s4 --epochs 30
    python -m benchmarks.reference --default-bundle    # + rebuild edge/models/default

Recipe (the paper's hyperparameters where they fit a CPU budget), run by the package's one
training loop (tactile_force.export.training, also used by ``tactile-force compress``): Adam,
L1 loss, batch 64, no augmentation, weights from scratch, seeded. The paper's lr 4e-5 for 25 epochs over
13k samples on a full ResNet-18 is scaled up to 1e-3 with cosine decay for the compact
networks, which otherwise do not converge within a CPU budget. The best epoch on the
validation indenters is kept. Split: the paper's S1 protocol (14 / 2 / 2 indenters).

Preprocessing is the exported graph's own (tactile_force.export.Preprocess); since it
has no parameters it is applied once to the whole dataset and cached.

Outputs (benchmarks/cache/, not committed): the synthetic dataset, depth images,
checkpoints, fp32 / int8 bundles and a JSON record per config with the test error.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CACHE = Path(os.environ.get("TACTILE_FORCE_CACHE", REPO / "benchmarks" / "cache"))
DEFAULT_BUNDLE_DIR = REPO / "edge" / "models" / "default"
REAL_DATA = REPO.parent / "shared" / "data" / "aurova_digit_grasp"

#: Dataset used by every reference model (changing it changes every figure in docs/).
DATASET_N = 4000
DATASET_SEED = 0
#: Share of samples drawn above the paper's 15 N (up to 20 N, where the gel is saturated).
#: Without them a model never outputs >= 15 N, so a saturated frame reads ~13-14 N and is
#: not flagged 'saturated'; with them it learns that a saturated gel means "15 N or more".
ABOVE_RANGE_SHARE = 0.06
SPLIT = "S1"


@dataclass(frozen=True)
class TrainConfig:
    """One reference model: variant, width multiplier, input scale 1/k, epochs, lr."""

    variant: str
    width: float
    k: int
    epochs: int = 30
    lr: float = 1e-3
    batch: int = 64
    seed: int = 0

    @property
    def name(self) -> str:
        return f"{self.variant}-w{self.width:g}-s{self.k}"

    @property
    def input_scale(self) -> float:
        return 1.0 / self.k


#: Configs trained by default. Full resolution (k=1, width 1) is ~2.8 GMAC a frame and
#: takes hours per epoch on a 2-core CPU: it is benchmarked for latency only.
CONFIGS: dict[str, TrainConfig] = {c.name: c for c in [
    TrainConfig("rgbmod", 0.25, 4, epochs=30),  # the embedded default model
    TrainConfig("d", 0.25, 4, epochs=15),
    TrainConfig("dmod", 0.25, 4, epochs=15),
    TrainConfig("rgbmod+d", 0.25, 4, epochs=15),
    TrainConfig("rgbmod", 0.5, 4, epochs=15),
    TrainConfig("rgbmod", 0.125, 8, epochs=15),
    TrainConfig("rgbmod", 0.25, 2, epochs=8),
]}

DEFAULT_MODEL = "rgbmod-w0.25-s4"


def log(msg: str) -> None:
    print(f"[reference {time.strftime('%H:%M:%S')}] {msg}", flush=True)


# ----------------------------------------------------------------------------- data

def dataset_root() -> Path:
    return CACHE / f"synth-n{DATASET_N}-seed{DATASET_SEED}-above{ABOVE_RANGE_SHARE:g}"


def ensure_dataset() -> Path:
    """Generate the synthetic dataset once (authors' layout + meta.jsonl)."""
    from tactile_force.edge.synthetic import DatasetOptions, generate_dataset

    root = dataset_root()
    if (root / "DONE").is_file():
        return root
    tmp = root.with_name(root.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    log(f"generating {DATASET_N} synthetic frames into {root}")
    from tactile_force.edge.synthetic import ForceDistribution

    summary = generate_dataset(tmp, DatasetOptions(n=DATASET_N, seed=DATASET_SEED, progress=False,
                                                   forces=ForceDistribution(above_fraction=ABOVE_RANGE_SHARE)))
    log(f"generated at {summary.frames_per_s:.0f} frames/s")
    (tmp / "DONE").write_text(json.dumps(summary.as_dict(), default=str, indent=2))
    shutil.rmtree(root, ignore_errors=True)
    os.replace(tmp, root)
    return root


@dataclass
class Arrays:
    """The whole dataset in memory: rgb (N,320,240,3) uint8 BGR, depth (N,320,240,1)
    uint8 or None, force (N,) N, ids, metadata, and split part per sample."""

    rgb: np.ndarray
    force: np.ndarray
    ids: list[int]
    meta: list[dict]
    part: np.ndarray
    depth: np.ndarray | None = None

    def select(self, part: str) -> np.ndarray:
        return np.flatnonzero(self.part == part)


def load_arrays(root: Path, with_depth: bool = False) -> Arrays:
    from tactile_force.edge import AuthorsDataset
    from tactile_force.edge.synthetic import paper_split, split_ids

    cache = root / "arrays.npz"
    if cache.is_file():
        z = np.load(cache, allow_pickle=False)
        rgb, force, ids = z["rgb"], z["force"], z["ids"].tolist()
    else:
        ds = AuthorsDataset(root)
        ids = list(ds.ids)
        rgb = np.stack([ds.load(n).frame for n in ids])
        force = ds.forces()
        np.savez(cache, rgb=rgb, force=force, ids=np.array(ids))
    ds_meta = AuthorsDataset(root).meta
    parts = split_ids(ds_meta, paper_split(SPLIT))
    part = np.full(len(ids), "other", dtype=object)
    pos = {n: i for i, n in enumerate(ids)}
    for name, members in parts.items():
        for n in members:
            part[pos[n]] = name
    arrays = Arrays(rgb=rgb, force=force.astype(np.float32), ids=ids, meta=[ds_meta.get(n, {}) for n in ids],
                    part=part.astype(str))
    if with_depth:
        arrays.depth = depth_images(root, arrays.rgb)
    return arrays


VIRTUAL_DEPTH_MAPPING = REPO / "edge" / "assets" / "virtual_digit_depth.npz"
#: 8-bit levels per pixel of reconstructed indentation for the virtual DIGIT. Its
#: reconstructed heights reach ~46 px at 15 N (p99 43 px), so 255 levels span 48 px; the
#: depth stage's default (255/20) would clip 69 % of the training frames at 255.
VIRTUAL_DEPTH_LEVELS_PER_PX = 255.0 / 48.0


def virtual_depth_stage():
    """The runtime's depth stage as the reference depth models were trained with it."""
    from tactile_force.edge import DepthOptions, DepthStage

    return DepthStage(DepthOptions(mapping=VIRTUAL_DEPTH_MAPPING, levels_per_px=VIRTUAL_DEPTH_LEVELS_PER_PX))


def depth_images(root: Path, rgb: np.ndarray) -> np.ndarray:
    """Depth images (N,320,240,1) uint8 of every frame, made as the runtime makes them:
    the contact gate's mask + the depth stage with the virtual DIGIT's calibration
    (benchmarks/virtual_depth_calibration.py). Cached next to the dataset."""
    from tactile_force.edge import ContactGate
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions

    cache = root / "depth.npy"
    if cache.is_file():
        return np.load(cache)
    log(f"computing depth images with the runtime's gate + depth stage ({VIRTUAL_DEPTH_MAPPING.name})")
    background = VirtualDigit(VirtualDigitOptions()).render(None, 0.0, led_gain=(1.0, 1.0, 1.0)).frame
    stage = virtual_depth_stage()
    out = np.zeros(rgb.shape[:3] + (1,), np.uint8)
    for i, frame in enumerate(rgb):
        gate = ContactGate()
        gate.capture_background([background])
        g = gate.update(frame)
        out[i] = stage.process(frame, g.mask).depth
    np.save(cache, out)
    return out


# ----------------------------------------------------------------------------- training

def train(cfg: TrainConfig, data: Arrays, out_dir: Path) -> dict:
    """Train one config with the package's training loop (tactile_force.export.training);
    returns its record (val/test error, epochs, time)."""
    from tactile_force.edge.metrics import error_report
    from tactile_force.export import ModelSpec, save_checkpoint
    from tactile_force.export.training import Frames, TrainOptions, predict, preprocess, train_network

    spec = ModelSpec(cfg.variant, cfg.width, cfg.input_scale)
    tr, va, te = data.select("train"), data.select("val"), data.select("test")

    def frames(idx: np.ndarray) -> Frames:
        inputs = {"rgb": data.rgb[idx]} if cfg.variant in ("rgbmod", "rgbmod+d") else {}
        if cfg.variant != "rgbmod":
            inputs["depth"] = data.depth[idx]  # type: ignore[index]
        return Frames(inputs, data.force[idx])

    def epoch_log(e) -> None:
        log(f"{cfg.name} epoch {e.epoch}/{cfg.epochs}: train L1 {e.train_l1:.3f} N, "
            f"val RE {e.val_re:.3f} MAE {e.val_mae:.3f} N ({e.seconds:.0f} s)")

    result = train_network(spec, frames(tr), frames(va),
                           TrainOptions(epochs=cfg.epochs, lr=cfg.lr, batch=cfg.batch, seed=cfg.seed), log=epoch_log)
    model = result.model
    history = [{"epoch": e.epoch, "train_l1": e.train_l1, "val_re": e.val_re, "val_mae": e.val_mae}
               for e in result.history]
    p_te = predict(model, preprocess(result.net, frames(te).inputs))
    groups = {g: [str(m.get(g, "?")) for m in (data.meta[i] for i in te)] for g in ("indenter", "stiffness", "location")}
    report = error_report(p_te, data.force[te], groups=groups)
    out_dir.mkdir(parents=True, exist_ok=True)
    record = {
        "config": asdict(cfg), "name": cfg.name, "best_epoch": result.best_epoch, "train_seconds": result.seconds,
        "n_train": len(tr), "n_val": len(va), "n_test": len(te), "split": SPLIT,
        "dataset": f"synthetic n={DATASET_N} seed={DATASET_SEED} ({ABOVE_RANGE_SHARE:.0%} at 15-20 N)",
        "test": report.as_dict(), "history": history,
    }
    save_checkpoint(out_dir / "model.pth", model, spec, extra={"trained_on": record["dataset"], "split": SPLIT,
                                                               "best_epoch": result.best_epoch})
    (out_dir / "record.json").write_text(json.dumps(record, indent=2))
    log(f"{cfg.name}: test {report.overall}")
    return record


# ----------------------------------------------------------------------------- bundles

def calibration_data(cfg: TrainConfig, data: Arrays, part: str, n: int | None = None):
    from tactile_force.export import CalibrationData

    idx = data.select(part)
    if n is not None:
        idx = np.random.default_rng(0).choice(idx, size=min(n, len(idx)), replace=False)
        idx.sort()
    inputs = {}
    if cfg.variant in ("rgbmod", "rgbmod+d"):
        inputs["rgb"] = data.rgb[idx]
    if cfg.variant != "rgbmod":
        inputs["depth"] = data.depth[idx]
    return CalibrationData(inputs=inputs, forces=data.force[idx], source=f"synthetic {part} split ({SPLIT})",
                           ids=[str(data.ids[i]) for i in idx])


def make_bundles(cfg: TrainConfig, data: Arrays, out_dir: Path, force: bool = False) -> dict[str, Path]:
    """fp32 and int8-static bundles of a trained config (parity on synthetic test frames)."""
    from tactile_force.export import ExportOptions, QuantizeOptions, export_bundle, quantize_bundle

    paths = {"fp32": out_dir / "fp32", "int8-static": out_dir / "int8"}
    if force or not paths["fp32"].is_dir():
        export_bundle(out_dir / "model.pth", paths["fp32"], ExportOptions(
            parity_data=calibration_data(cfg, data, "test", 32), name=f"{cfg.name}-fp32", overwrite=True,
            trained_on=f"synthetic DIGIT frames (n={DATASET_N}, seed {DATASET_SEED}, split {SPLIT} train)"))
    if force or not paths["int8-static"].is_dir():
        quantize_bundle(paths["fp32"], paths["int8-static"],
                        QuantizeOptions(mode="int8-static", method="minmax", name=f"{cfg.name}-int8", overwrite=True),
                        calibration=calibration_data(cfg, data, "train", 200),
                        eval_data=calibration_data(cfg, data, "test"))
    if cfg.variant != "rgbmod":
        for path in paths.values():
            record_depth_mapping(path)
    return paths


def record_depth_mapping(bundle_dir: Path) -> None:
    """Write into a depth bundle's manifest which depth mapping made its training images,
    so a scene without a [depth] table builds the same depth stage (idempotent)."""
    from tactile_force.edge.bundle import load_bundle, sha256_file, write_bundle
    from tactile_force.edge.manifest import DepthRecord

    b = load_bundle(bundle_dir)
    want = DepthRecord(mapping=f"package:{VIRTUAL_DEPTH_MAPPING.name}", mode="exact",
                       levels_per_px=VIRTUAL_DEPTH_LEVELS_PER_PX,
                       mapping_sha256=sha256_file(VIRTUAL_DEPTH_MAPPING), mask="contact gate (GateOptions defaults)")
    if b.manifest.depth != want:
        b.manifest.depth = want
        write_bundle(bundle_dir, b.onnx_path.read_bytes(), b.manifest, overwrite=True)


DEFAULT_NOTE = ("Trained on SYNTHETIC frames from the package's virtual DIGIT only. It runs the demo and "
                "the tests; it does not know your sensor. Replace it with a model trained on your own "
                "labelled DIGIT frames before trusting its newtons on a real gripper.")


def install_default_bundle(int8_bundle: Path) -> Path:
    """Copy a trained int8 bundle into edge/models/default with the synthetic-data note."""
    from tactile_force.edge.bundle import load_bundle, write_bundle

    src = load_bundle(int8_bundle)
    manifest = src.manifest
    manifest.name = "default-rgbmod-compact-int8"
    manifest.provenance.note = DEFAULT_NOTE
    manifest.provenance.trained_on = "synthetic"
    return write_bundle(DEFAULT_BUNDLE_DIR, src.onnx_path.read_bytes(), manifest, overwrite=True).path


# ----------------------------------------------------------------------------- CLI

def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.reference", description=__doc__.split("\n\n")[0])
    ap.add_argument("--configs", default=",".join(CONFIGS), help=f"comma list of {', '.join(CONFIGS)}")
    ap.add_argument("--epochs", type=int, default=None, help="override every config's epochs")
    ap.add_argument("--retrain", action="store_true", help="ignore cached checkpoints")
    ap.add_argument("--default-bundle", action="store_true",
                    help=f"install {DEFAULT_MODEL}'s int8 bundle as edge/models/default")
    args = ap.parse_args(argv)
    names = [c for c in args.configs.split(",") if c]
    unknown = [c for c in names if c not in CONFIGS]
    if unknown:
        ap.error(f"unknown configs {unknown}; choose from {list(CONFIGS)}")
    root = ensure_dataset()
    need_depth = any(CONFIGS[c].variant != "rgbmod" for c in names)
    data = load_arrays(root, with_depth=need_depth)
    log(f"dataset: {len(data.ids)} frames, train {len(data.select('train'))}, val {len(data.select('val'))}, "
        f"test {len(data.select('test'))}")
    for name in names:
        cfg = CONFIGS[name]
        if args.epochs:
            cfg = TrainConfig(cfg.variant, cfg.width, cfg.k, args.epochs, cfg.lr, cfg.batch, cfg.seed)
        out = CACHE / "models" / name
        if args.retrain or not (out / "record.json").is_file():
            train(cfg, data, out)
        make_bundles(cfg, data, out, force=args.retrain)
    if args.default_bundle:
        path = install_default_bundle(CACHE / "models" / DEFAULT_MODEL / "int8")
        log(f"installed default bundle at {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
