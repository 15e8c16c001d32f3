"""Reference models: a reproducible CPU training recipe on synthetic DIGIT frames.

Training lives outside this package; this recipe exists so that the benchmarks can
report error against run time with real trained weights, and so the embedded default
model can be rebuilt by anyone:

    python -m benchmarks.reference                     # every config in CONFIGS
    python -m benchmarks.reference --configs rgbmod-w0.25-s4 --epochs 30
    python -m benchmarks.reference --default-bundle    # + install the trained default (full-resolution graph)
    python -m benchmarks.reference --network-input-default   # edge/models/default as shipped (graph surgery)

Recipe (the paper's hyperparameters where they fit a CPU budget), run by the package's one
training loop (tactile_force.export.training, also used by ``tactile-force compress``): Adam,
L1 loss, batch 64, no augmentation, weights from scratch, seeded. The paper's lr 4e-5 for 25 epochs over
13k samples on a full ResNet-18 is scaled up to 1e-3 with cosine decay for the compact
networks, which otherwise do not converge within a CPU budget. The best epoch on the
validation indenters is kept. Split: the paper's S1 protocol (14 / 2 / 2 indenters).

Preprocessing is the exported graph's own (tactile_force.export.Preprocess); since it
has no parameters it is applied once to the whole dataset and cached.

Compact depth configs (D, Dmod, RGBmod+D at input scale 1/k < 1) train at the network
resolution: every frame is reduced once to 320/k x 240/k (the bundle's recorded reduction)
and the runtime's own depth stage makes the depth image on that reduced frame with the
contact gate's mask (``DepthOptions(downscale=k)``, docs/depth.md), so training and runtime
make the same depth. Their graphs start at the network resolution.

    python -m benchmarks.reference --configs d-w0.125-s4,rgbmod+d-w0.125-s4 --shipped-bundles

installs the shipped compact D and RGBmod+D bundles (edge/models/d, edge/models/rgbmod_d).

    python -m benchmarks.reference --configs rgbmod-w0.125-s4-b1111 --fast-bundle

trains the fast bundle's config (one residual block per stage) and installs it as
edge/models/fast once its synthetic test RE is within 0.03 of the default's.

Outputs (the cache dir, benchmarks/cache/ in a clone or $TACTILE_FORCE_CACHE; not committed):
the synthetic dataset, depth images,
checkpoints, fp32 / int8 bundles and a JSON record per config with the test error.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
from tactile_force.edge.errors import TactileForceError
from tactile_force.edge.scene import PACKAGE_DIR, default_bundle_path

from .harness.data import Labelled, predict_all
from .harness.frames import (
    VIRTUAL_DEPTH_MAPPING,
    network_reduction,
    virtual_depth_record,
    virtual_depth_stage,
)
from .harness.paths import cache_dir, require_repo

#: Dataset used by every reference model (changing it changes every figure in docs/).
DATASET_N = 4000
DATASET_SEED = 0
#: Share of samples drawn above the paper's 15 N (up to 20 N, where the gel is saturated).
#: Without them a model never outputs >= 15 N, so a saturated frame reads ~13-14 N and is
#: not flagged 'saturated'; with them it learns that a saturated gel means "15 N or more".
ABOVE_RANGE_SHARE = 0.06
SPLIT = "S1"
#: torch threads for training (None: all cores; TACTILE_FORCE_TRAIN_THREADS on a shared host)
THREADS = int(os.environ["TACTILE_FORCE_TRAIN_THREADS"]) if os.environ.get("TACTILE_FORCE_TRAIN_THREADS") else None


@dataclass(frozen=True)
class TrainConfig:
    """One reference model: variant, width multiplier, input scale 1/k, epochs, lr, and
    residual blocks per stage (ResNet-18's (2, 2, 2, 2) unless fewer; a name suffix '-b1111')."""

    variant: str
    width: float
    k: int
    epochs: int = 30
    lr: float = 1e-3
    batch: int = 64
    seed: int = 0
    blocks: tuple[int, int, int, int] = (2, 2, 2, 2)

    @property
    def name(self) -> str:
        from tactile_force.export.zoo import blocks_tag

        return f"{self.variant}-w{self.width:g}-s{self.k}{blocks_tag(self.blocks)}"

    @property
    def input_scale(self) -> float:
        return 1.0 / self.k


#: The fast bundle's width multiplier (see :data:`FAST_MODEL`).
FAST_WIDTH = 0.125

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
    # the shipped compact depth bundles (edge/models/d, edge/models/rgbmod_d): width 1/8 keeps
    # each int8 graph at a few hundred kB; 60 epochs: about 4 and 9 min on one shared core
    TrainConfig("d", 0.125, 4, epochs=60),
    TrainConfig("rgbmod+d", 0.125, 4, epochs=60),
    # the fast bundle (edge/models/fast): one residual block per stage at the default's width
    # and input, FAST_TARGETS below
    TrainConfig("rgbmod", FAST_WIDTH, 4, epochs=30, blocks=(1, 1, 1, 1)),
]}

#: Shipped bundle folder under edge/models -> the config it is built from.
SHIPPED_DEPTH_BUNDLES = {"d": "d-w0.125-s4", "rgbmod_d": "rgbmod+d-w0.125-s4"}

DEFAULT_MODEL = "rgbmod-w0.25-s4"

#: The fast shipped bundle (edge/models/fast): RGBmod with one residual block per stage;
#: ``--fast-bundle`` installs it. Its goals against the default, both measured on this recipe:
#: at most FAST_TARGETS["instructions"] x the default's instructions per bare call
#: (benchmarks/bare_instructions.py) and RE on the synthetic test split within
#: FAST_TARGETS["re_margin"] of the default's.
FAST_MODEL = f"rgbmod-w{FAST_WIDTH:g}-s4-b1111"
FAST_TARGETS = {"instructions": 0.5, "re_margin": 0.03}


def network_resolution(cfg: TrainConfig) -> bool:
    """True for configs trained (and exported) at the network resolution: compact depth
    variants, whose depth is made on the reduced frame."""
    return cfg.variant != "rgbmod" and cfg.k > 1


def reduce_frames(frames: np.ndarray, k: int) -> np.ndarray:
    """(N, 320, 240, C) uint8 -> (N, 320/k, 240/k, C) uint8 with the network reduction."""
    from tactile_force.edge.gate.reduce import reduce_frames as _reduce

    return _reduce(frames, network_reduction(k))


def log(msg: str) -> None:
    print(f"[reference {time.strftime('%H:%M:%S')}] {msg}", flush=True)


# ----------------------------------------------------------------------------- data

def dataset_root() -> Path:
    return cache_dir() / f"synth-n{DATASET_N}-seed{DATASET_SEED}-above{ABOVE_RANGE_SHARE:g}"


def dataset_options():
    """The reference dataset's :class:`tactile_force.edge.synthetic.DatasetOptions`."""
    from tactile_force.edge.synthetic import DatasetOptions, ForceDistribution

    return DatasetOptions(n=DATASET_N, seed=DATASET_SEED, progress=False,
                          forces=ForceDistribution(above_fraction=ABOVE_RANGE_SHARE))


def heldout_test_split(limit: int = 0) -> list[tuple[int, np.ndarray, float, dict]]:
    """The held-out test split (:data:`SPLIT`'s test indenters) of the reference dataset,
    rendered alone by the virtual DIGIT (seconds, no torch, no cache): (sample number, frame
    320 x 240 x 3 uint8 BGR, force N, metadata), bit for bit the frames :func:`ensure_dataset`
    writes for them; ``limit`` > 0: the first ``limit`` only."""
    from tactile_force.edge.synthetic import paper_split, render_samples

    out = render_samples(dataset_options(), paper_split(SPLIT).test)
    return out[:limit] if limit else out


def ensure_dataset() -> Path:
    """Generate the synthetic dataset once (authors' layout + meta.jsonl)."""
    from tactile_force.edge.synthetic import generate_dataset

    root = dataset_root()
    if (root / "DONE").is_file():
        return root
    tmp = root.with_name(root.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    log(f"generating {DATASET_N} synthetic frames into {root}")
    summary = generate_dataset(tmp, dataset_options())
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
    #: network-resolution inputs by k: {"rgb": (N,320/k,240/k,3), "depth": (N,320/k,240/k,1)}
    reduced: dict[int, dict[str, np.ndarray]] | None = None

    def select(self, part: str) -> np.ndarray:
        return np.flatnonzero(self.part == part)

    def inputs(self, cfg: TrainConfig, idx: np.ndarray) -> dict[str, np.ndarray]:
        """The network inputs of config ``cfg`` for samples ``idx`` (raw uint8 frames; at
        the network resolution for :func:`network_resolution` configs)."""
        if network_resolution(cfg):
            assert self.reduced is not None and cfg.k in self.reduced, "load_arrays(depth_downscales=...)"
            src = self.reduced[cfg.k]
        else:
            src = {"rgb": self.rgb, **({"depth": self.depth} if self.depth is not None else {})}
        return {n: src[n][idx] for n in _input_names(cfg)}

    def full_inputs(self, cfg: TrainConfig, idx: np.ndarray) -> dict[str, np.ndarray]:
        """The inputs as export and quantization take them (320 x 240 frames, reduced by the
        graph's recorded reduction): the full-resolution rgb frames, and for network-resolution
        configs each grid depth image repeated over its k x k block (any box-average reduction
        gives it back exactly)."""
        if not network_resolution(cfg):
            return self.inputs(cfg, idx)
        out = {}
        for n in _input_names(cfg):
            if n == "rgb":
                out[n] = self.rgb[idx]
            else:
                assert self.reduced is not None
                out[n] = np.repeat(np.repeat(self.reduced[cfg.k]["depth"][idx], cfg.k, axis=1), cfg.k, axis=2)
        return out


def _input_names(cfg: TrainConfig) -> list[str]:
    return (["rgb"] if cfg.variant in ("rgbmod", "rgbmod+d") else []) + (["depth"] if cfg.variant != "rgbmod" else [])


def load_arrays(root: Path, with_depth: bool = False, depth_downscales: tuple[int, ...] = ()) -> Arrays:
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
        arrays.depth = depth_images(root, arrays.rgb, 1, arrays.meta)
    arrays.reduced = {}
    for k in depth_downscales:
        arrays.reduced[k] = {"rgb": reduce_frames(arrays.rgb, k),
                             "depth": depth_images(root, arrays.rgb, k, arrays.meta)}
    return arrays


def depth_images(root: Path, rgb: np.ndarray, downscale: int = 1, meta: list[dict] | None = None) -> np.ndarray:
    """Depth images of every frame, made as the runtime makes them: the contact gate's
    mask + the depth stage with the virtual DIGIT's calibration
    (benchmarks/virtual_depth_calibration.py); (N,320,240,1) uint8, or at ``downscale`` k
    (N,320/k,240/k,1) made on the reduced frame. Cached next to the dataset."""
    from tactile_force.edge import ContactGate, GateOptions
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions

    cache = root / f"depth-s{downscale}.npy"  # v2: gate background rendered with each frame's LED gains
    skipped = 0
    if cache.is_file():
        return np.load(cache)
    log(f"computing depth images (downscale {downscale}) with the runtime's gate + depth stage "
        f"({VIRTUAL_DEPTH_MAPPING.name})")
    digit = VirtualDigit(VirtualDigitOptions())
    backgrounds: dict[tuple[float, ...], np.ndarray] = {}
    stage = virtual_depth_stage(downscale)
    out = np.zeros((rgb.shape[0], *stage.output_shape), np.uint8)
    for i, frame in enumerate(rgb):
        # the gate's background is the sensor's own no-contact frame, as a runtime learns it:
        # the virtual DIGIT rendered with this frame's LED gains (its grasp's)
        gain = tuple(float(v) for v in (meta[i].get("led_gain") if meta else None) or (1.0, 1.0, 1.0))
        if gain not in backgrounds:
            backgrounds[gain] = digit.render(None, 0.0, led_gain=gain, rng=np.random.default_rng(0)).frame
        gate = ContactGate()
        gate.capture_background([backgrounds[gain]])
        g = gate.update(frame)
        if g.mismatch or g.invalid:
            # judged from one frame the gate calls a very large press a mismatch; in a stream it
            # tracks a press that grew while it watched: take its mask with the judging off
            skipped += 1
            gate = ContactGate(GateOptions(trust=False))
            gate.capture_background([backgrounds[gain]])
            g = gate.update(frame)
        out[i] = stage.process(frame, g.mask).depth
    log(f"depth images: {skipped} of {len(out)} frames the gate judged a mismatch from one frame "
        "(mask taken with its judging off)")
    tmp = cache.with_name(cache.name + ".partial.npy")
    np.save(tmp, out)
    os.replace(tmp, cache)
    return out


# ----------------------------------------------------------------------------- labelled frames

def synthetic_test(with_depth: bool) -> Labelled:
    """The held-out-indenter test split of the reference dataset."""
    arrays = load_arrays(ensure_dataset(), with_depth=with_depth)
    idx = arrays.select("test")
    return Labelled(arrays.rgb[idx], arrays.depth[idx] if with_depth else None, arrays.force[idx].astype(np.float64),
                    f"synthetic test split ({SPLIT}, held-out indenters, {len(idx)} frames)")




# ----------------------------------------------------------------------------- training

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


# ----------------------------------------------------------------------------- bundles

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


DEFAULT_NOTE = ("Trained on SYNTHETIC frames from the package's virtual DIGIT only. It runs the demo and "
                "the tests; it does not know your sensor. Replace it with a model trained on your own "
                "labelled DIGIT frames before trusting its newtons on a real gripper.")


def install_default_bundle(int8_bundle: Path) -> Path:
    """Copy a trained int8 bundle into the package's models/default with the synthetic-data note."""
    from tactile_force.edge.bundle.store import load_bundle, write_bundle

    src = load_bundle(int8_bundle)
    manifest = src.manifest
    manifest.name = "default-rgbmod-compact-int8"
    manifest.provenance.note = DEFAULT_NOTE
    manifest.provenance.trained_on = "synthetic"
    return write_bundle(default_bundle_path(), src.onnx_path.read_bytes(), manifest, overwrite=True).path


#: The default graph as the reference recipe installed it before the network-input cut (a
#: loadable bundle: full-resolution uint8 input, the 4x4 AveragePool inside the graph), in the clone.
REFERENCE_GRAPH = Path("benchmarks") / "reference_graphs" / "default_c1733e6.onnx"


def network_input_default(dest: Path | None = None) -> Path:
    """Rebuild the shipped default bundle: :data:`REFERENCE_GRAPH` cut at the network
    resolution (:func:`tactile_force.export.network_input.network_input_bundle`, same
    weights), the package's reduction at x4 recorded, its error re-measured on the
    synthetic test split."""
    import tempfile
    from dataclasses import replace

    from tactile_force.edge import OnnxForceModel, load_bundle
    from tactile_force.edge.bundle.manifest import ErrorFigures
    from tactile_force.edge.bundle.store import write_bundle
    from tactile_force.edge.data.metrics import error_stats
    from tactile_force.export.network_input import network_input_bundle

    src = require_repo("rebuilding the shipped default from its reference graph") / REFERENCE_GRAPH
    dest = dest or default_bundle_path()
    red = network_reduction(4)
    with tempfile.TemporaryDirectory() as tmp:
        b = network_input_bundle(src, Path(tmp) / "b", red, name="default-rgbmod-compact-int8")
        syn = synthetic_test(False)
        stats = error_stats(predict_all(OnnxForceModel(b), syn), syn.force)
        m = b.manifest
        assert m.error is not None
        # The graph's forces changed by the reduction's rounding: re-measured; the fp32 graph's
        # figures stay what they were (it was measured with the in-graph average).
        m.error = replace(m.error, data=f"{syn.source}; reduced by {red.method.value} x{red.factor}",
                          frames=len(syn.force), vs_truth=ErrorFigures(**stats.as_dict()), vs_fp32=None)
        m.provenance.extra = {**m.provenance.extra,
                              "network_input": f"graph surgery of the c1733e6 default (4x4 AveragePool removed, "
                                               f"same weights): python -m benchmarks.reference "
                                               f"--network-input-default; frames reduced by {red.method.value} "
                                               f"x{red.factor}"}
        out = write_bundle(dest, b.onnx_path.read_bytes(), m, overwrite=True)
    log(f"wrote {out.path}: synthetic test {stats}")
    return load_bundle(dest).path


DEPTH_NOTE = ("Trained on SYNTHETIC frames from the package's virtual DIGIT only, with depth images made at the "
              "network resolution (80 x 60) by the runtime's depth stage from the virtual DIGIT's shipped "
              "calibration (package:virtual_digit_depth.npz). It lets the robot side compare D / RGBmod+D with "
              "RGBmod (tactile-force bench); it does not know your sensor. On a real DIGIT, calibrate the depth "
              "stage (calibrate-depth) and train on your own labelled frames before trusting its newtons.")


def default_data_stats(n: int = 600, seed: int = 0):
    """data_stats for the embedded default bundle: ``n`` frames drawn like its training set
    (benchmarks.reference: the virtual DIGIT, the paper's 18 indenters, 6 % above 15 N, LED
    spread 3 %) seen through the gate against the shipped no-contact background. Cached in
    the cache dir as trust_data_stats-nN-seedS.json."""
    import tempfile

    import cv2
    from tactile_force.edge import AuthorsDataset
    from tactile_force.edge.bundle.data_stats import DataStats
    from tactile_force.edge.fitting.data_stats import compute_data_stats
    from tactile_force.edge.synthetic import DatasetOptions, ForceDistribution, generate_dataset
    from tactile_force.edge.typed_json import from_json, to_json

    cache = cache_dir() / f"trust_data_stats-n{n}-seed{seed}.json"
    if cache.is_file():
        import json

        return from_json(DataStats, json.loads(cache.read_text()), "data_stats")
    with tempfile.TemporaryDirectory() as tmp:
        generate_dataset(Path(tmp) / "ds", DatasetOptions(n=n, seed=seed, progress=False,
                                                          forces=ForceDistribution(above_fraction=ABOVE_RANGE_SHARE)))
        ds = AuthorsDataset(Path(tmp) / "ds")
        frames = [ds[i].frame for i in range(len(ds))]
    bg = cv2.imread(str(PACKAGE_DIR / "assets" / "digit_background.png"))
    stats = compute_data_stats(frames, bg, source=f"{n} synthetic frames drawn like the default bundle's training set "
                                                  f"(virtual DIGIT, paper indenters, seed {seed})")
    cache.parent.mkdir(parents=True, exist_ok=True)
    import json

    cache.write_text(json.dumps(to_json(stats), indent=1))
    return stats


def attach_data_stats(bundle_dir: Path, stats) -> None:
    """Store ``stats`` as the manifest's data_stats of the bundle folder (rewritten atomically)."""
    from tactile_force.edge.bundle.store import load_bundle, write_bundle

    b = load_bundle(bundle_dir)
    b.manifest.data_stats = stats
    write_bundle(bundle_dir, b.onnx_path.read_bytes(), b.manifest, overwrite=True)


def install_shipped_bundle(folder: str, bundle: Path, note: str = DEPTH_NOTE) -> Path:
    """Copy a trained bundle into edge/models/<folder> with the synthetic-data ``note`` (the
    depth bundles': :data:`DEPTH_NOTE`) and the default bundle's data statistics (the same
    training distribution, seen by the gate)."""
    from tactile_force.edge.bundle.store import load_bundle, write_bundle

    src = load_bundle(bundle)
    m = src.manifest
    precision = "int8" if m.precision.value == "int8-static" else m.precision.value
    m.name = f"{folder.replace('_', '+')}-compact-{precision}"
    m.provenance.note = note
    m.provenance.trained_on = "synthetic"
    m.data_stats = default_data_stats()
    if hasattr(m, "data_stats_missing"):
        m.data_stats_missing = ""
    m.provenance.extra["node_metadata_stripped"] = True
    m.provenance.extra["identity_input_quantizers_dropped"] = True
    graph = strip_node_metadata(src.onnx_path.read_bytes())
    if m.quantization is not None:
        import onnx
        from tactile_force.export.graph import op_counts

        m.quantization.op_counts = dict(op_counts(onnx.load_from_string(graph)))
    path = write_bundle(default_bundle_path().parent / folder, graph, m, overwrite=True).path
    from .interval_fit import fit_bundle

    fit_bundle(path)  # the reading interval of this graph (the source's was fitted on another sha256)
    return path


FAST_NOTE = ("Trained on SYNTHETIC frames from the package's virtual DIGIT only, like the default bundle, at half "
             "its width with one residual block per stage (a model call about half the default's instructions; a "
             "reading also pays the contact gate, docs/benchmarks/instructions.md) for hosts where the default does "
             "not hold its latency budget. It does not know your sensor: train on your own labelled DIGIT frames "
             "(or distil your model with 'tactile-force compress') before trusting its newtons.")


class FastBundleError(TactileForceError):
    """A trained fast bundle that misses its goal against the default; nothing was installed."""


def install_fast_bundle(int8_bundle: Path) -> Path:
    """Install a trained :data:`FAST_MODEL` int8 bundle as edge/models/fast
    (:func:`install_shipped_bundle` with :data:`FAST_NOTE`) after checking its goals against
    the shipped default: RE on the synthetic test split (both manifests' ``error.vs_truth``,
    measured on the same frames with the runtime's reduction) within
    ``FAST_TARGETS["re_margin"]``; the instruction count is checked by
    ``python -m benchmarks.bare_instructions edge/models/default edge/models/fast``."""
    from tactile_force.edge.bundle.store import load_bundle

    fast, default = load_bundle(int8_bundle).manifest, load_bundle(default_bundle_path()).manifest
    if fast.error is None or fast.error.vs_truth is None or default.error is None or default.error.vs_truth is None:
        raise FastBundleError(f"{int8_bundle}: this bundle and the default need error.vs_truth on the synthetic test "
                              "split (make_bundles measures it)")
    re_fast, re_default = fast.error.vs_truth.re_mean, default.error.vs_truth.re_mean
    if re_fast > re_default + FAST_TARGETS["re_margin"]:
        raise FastBundleError(f"{int8_bundle}: synthetic test RE {re_fast:.4f} is more than "
                              f"{FAST_TARGETS['re_margin']} above the default's {re_default:.4f}; train longer "
                              "(--epochs) before installing it")
    path = install_shipped_bundle("fast", int8_bundle, FAST_NOTE)
    log(f"fast bundle: synthetic test RE {re_fast:.4f} (default {re_default:.4f})")
    return path


def strip_node_metadata(model_bytes: bytes) -> bytes:
    """The graph without its nodes' doc strings and metadata (the exporter's source locations)
    and without identity input quantizers: the same computation, about a fifth smaller.

    An int8 graph's uint8 input that runs Transpose -> Cast -> QuantizeLinear(scale 1, zero
    point 0, uint8) is its own quantized value: the Transpose's output feeds the quantizer's
    users and the Cast and the QuantizeLinear go (the exact rewrite export/network_input.py
    applies to the default bundle)."""
    import onnx
    from onnx import numpy_helper

    model = onnx.load_from_string(model_bytes)
    g = model.graph
    for node in g.node:
        del node.metadata_props[:]
        node.doc_string = ""
    inits = {t.name: t for t in g.initializer}

    def users(name: str) -> list:
        return [n for n in g.node if name in n.input]

    for inp in g.input:
        t = users(inp.name)
        if len(t) != 1 or t[0].op_type != "Transpose":
            continue
        c = users(t[0].output[0])
        if len(c) != 1 or c[0].op_type != "Cast":
            continue
        q = users(c[0].output[0])
        if len(q) != 1 or q[0].op_type != "QuantizeLinear" or len(q[0].input) < 3:
            continue
        scale, zp = inits.get(q[0].input[1]), inits.get(q[0].input[2])
        if scale is None or zp is None:
            continue
        sv, zv = numpy_helper.to_array(scale), numpy_helper.to_array(zp)
        if not (sv.size == 1 and float(sv) == 1.0 and zv.size == 1 and int(zv) == 0 and zv.dtype == np.uint8):
            continue
        for n in users(q[0].output[0]):
            for i, x in enumerate(n.input):
                if x == q[0].output[0]:
                    n.input[i] = t[0].output[0]
        g.node.remove(c[0])
        g.node.remove(q[0])
    onnx.checker.check_model(model)
    return model.SerializeToString()


# ----------------------------------------------------------------------------- CLI

def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.reference", description=__doc__.split("\n\n")[0])
    ap.add_argument("--configs", default=",".join(CONFIGS), help=f"comma list of {', '.join(CONFIGS)}")
    ap.add_argument("--epochs", type=int, default=None, help="override every config's epochs")
    ap.add_argument("--retrain", action="store_true", help="ignore cached checkpoints")
    ap.add_argument("--default-bundle", action="store_true",
                    help=f"install {DEFAULT_MODEL}'s int8 bundle as edge/models/default")
    ap.add_argument("--network-input-default", action="store_true",
                    help="rebuild edge/models/default as shipped: the default graph of benchmarks/reference_graphs "
                         "cut at the network resolution (no training)")
    ap.add_argument("--shipped-bundles", action="store_true",
                    help="install the int8 bundles of " + ", ".join(SHIPPED_DEPTH_BUNDLES.values())
                    + " as edge/models/" + ", edge/models/".join(SHIPPED_DEPTH_BUNDLES))
    ap.add_argument("--fast-bundle", action="store_true",
                    help=f"install {FAST_MODEL}'s int8 bundle as edge/models/fast (train it: --configs {FAST_MODEL})")
    args = ap.parse_args(argv)
    if args.network_input_default:
        network_input_default()
        return 0
    names = [c for c in args.configs.split(",") if c]
    unknown = [c for c in names if c not in CONFIGS]
    if unknown:
        ap.error(f"unknown configs {unknown}; choose from {list(CONFIGS)}")
    root = ensure_dataset()
    need_depth = any(CONFIGS[c].variant != "rgbmod" and not network_resolution(CONFIGS[c]) for c in names)
    downscales = tuple(sorted({CONFIGS[c].k for c in names if network_resolution(CONFIGS[c])}))
    data = load_arrays(root, with_depth=need_depth, depth_downscales=downscales)
    log(f"dataset: {len(data.ids)} frames, train {len(data.select('train'))}, val {len(data.select('val'))}, "
        f"test {len(data.select('test'))}")
    for name in names:
        cfg = CONFIGS[name]
        if args.epochs:
            cfg = replace(cfg, epochs=args.epochs)
        out = cache_dir() / "models" / name
        if args.retrain or not (out / "record.json").is_file():
            train(cfg, data, out)
        make_bundles(cfg, data, out, force=args.retrain)
    if args.default_bundle:
        path = install_default_bundle(cache_dir() / "models" / DEFAULT_MODEL / "int8")
        log(f"installed default bundle at {path}")
    if args.shipped_bundles:
        for folder, name in SHIPPED_DEPTH_BUNDLES.items():
            path = install_shipped_bundle(folder, cache_dir() / "models" / name / "int8")
            log(f"installed {name} at {path}")
    if args.fast_bundle:
        path = install_fast_bundle(cache_dir() / "models" / FAST_MODEL / "int8")
        log(f"installed {FAST_MODEL} at {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
