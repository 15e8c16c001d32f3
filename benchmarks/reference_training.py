"""The reference recipe's training: one config trained with the package's training loop, then
its fp32 and int8-static bundles (with the depth mapping recorded in depth bundles)
(benchmarks/reference.py)."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .harness.frames import network_reduction, virtual_depth_record
from .reference_configs import (
    ABOVE_RANGE_SHARE,
    DATASET_N,
    DATASET_SEED,
    SPLIT,
    THREADS,
    TrainConfig,
    log,
    network_resolution,
)
from .reference_data import Arrays


def train(cfg: TrainConfig, data: Arrays, out_dir: Path) -> dict:
    """Train one config with the package's training loop (tactile_force.export.training);
    returns its record (val/test error, epochs, time)."""
    from tactile_force.edge.data.metrics import error_report
    from tactile_force.export import ModelSpec, save_checkpoint
    from tactile_force.export.training import Frames, TrainOptions, predict, preprocess, train_network

    spec = ModelSpec(cfg.variant, cfg.width, cfg.input_scale, cfg.blocks)
    # network-resolution configs get frames already reduced to the network input: the
    # network trains without an in-graph pool (input scale 1 on the reduced frames)
    train_spec = ModelSpec(cfg.variant, cfg.width, 1.0, cfg.blocks) if network_resolution(cfg) else spec
    tr, va, te = data.select("train"), data.select("val"), data.select("test")

    def frames(idx: np.ndarray) -> Frames:
        return Frames(data.inputs(cfg, idx), data.force[idx])

    def epoch_log(e) -> None:
        log(f"{cfg.name} epoch {e.epoch}/{cfg.epochs}: train L1 {e.train_l1:.3f} N, "
            f"val RE {e.val_re:.3f} MAE {e.val_mae:.3f} N ({e.seconds:.0f} s)")

    result = train_network(train_spec, frames(tr), frames(va),
                           TrainOptions(epochs=cfg.epochs, lr=cfg.lr, batch=cfg.batch, seed=cfg.seed,
                                        threads=THREADS), log=epoch_log)
    model = result.model
    history = [{"epoch": e.epoch, "train_l1": e.train_l1, "val_re": e.val_re, "val_mae": e.val_mae}
               for e in result.history]
    p_te = predict(model, preprocess(result.net, frames(te).inputs))
    groups = {g: [str(m.get(g, "?")) for m in (data.meta[i] for i in te)]
              for g in ("indenter", "stiffness", "location")}
    report = error_report(p_te, data.force[te], groups=groups)
    out_dir.mkdir(parents=True, exist_ok=True)
    record = {
        "config": asdict(cfg), "name": cfg.name, "best_epoch": result.best_epoch, "train_seconds": result.seconds,
        "n_train": len(tr), "n_val": len(va), "n_test": len(te), "split": SPLIT,
        "dataset": f"synthetic n={DATASET_N} seed={DATASET_SEED} ({ABOVE_RANGE_SHARE:.0%} at 15-20 N)",
        "test": report.as_dict(), "history": history,
    }
    extra = {"trained_on": record["dataset"], "split": SPLIT, "best_epoch": result.best_epoch}
    if network_resolution(cfg):
        extra["network_input"] = f"reduced {network_reduction(cfg.k).method.value} x{cfg.k}"
    save_checkpoint(out_dir / "model.pth", model, spec, extra=extra)
    (out_dir / "record.json").write_text(json.dumps(record, indent=2))
    log(f"{cfg.name}: test {report.overall}")
    return record


def calibration_data(cfg: TrainConfig, data: Arrays, part: str, n: int | None = None):
    from tactile_force.export import CalibrationData

    idx = data.select(part)
    if n is not None:
        idx = np.random.default_rng(0).choice(idx, size=min(n, len(idx)), replace=False)
        idx.sort()
    inputs = data.full_inputs(cfg, idx)
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
            record_depth_mapping(path, cfg.k if network_resolution(cfg) else 1)
    return paths


def record_depth_mapping(bundle_dir: Path, downscale: int = 1) -> None:
    """Write into a depth bundle's manifest which depth mapping made its training images and
    on which grid (``downscale``), so a scene without a [depth] table builds the same depth
    stage (idempotent)."""
    from tactile_force.edge.bundle.store import load_bundle, write_bundle

    b = load_bundle(bundle_dir)
    want = virtual_depth_record(downscale)
    if b.manifest.depth != want:
        b.manifest.depth = want
        write_bundle(bundle_dir, b.onnx_path.read_bytes(), b.manifest, overwrite=True)
