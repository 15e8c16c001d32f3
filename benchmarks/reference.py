"""Reference models: a reproducible CPU training recipe on synthetic DIGIT frames.

Training lives outside this package; this recipe exists so that the benchmarks can
report error against run time with real trained weights, and so the embedded default
model can be rebuilt by anyone:

    python -m benchmarks.reference                     # every config in CONFIGS
    python -m benchmarks.reference --configs rgbmod-w0.25-s4 --epochs 30
    python -m benchmarks.reference --default-bundle    # + install the trained default (full-resolution graph)
    python -m benchmarks.reference --network-input-int8      # edge/models/rgbmod_int8 as shipped (graph surgery)

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

trains the default bundle's config (one residual block per stage, fp32) and installs it as
edge/models/default once its synthetic test RE is within 0.03 of the int8 RGBmod's.

The recipe's parts: reference_configs.py (configs), reference_data.py (the synthetic dataset,
depth images), reference_training.py (training, bundles), reference_install.py (the shipped
bundles); this module is the command.

Outputs (the cache dir, benchmarks/cache/ in a clone or $TACTILE_FORCE_CACHE; not committed):
the synthetic dataset, depth images,
checkpoints, fp32 / int8 bundles and a JSON record per config with the test error.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from .harness.paths import cache_dir
from .reference_configs import (
    ABOVE_RANGE_SHARE,
    CONFIGS,
    DATASET_N,
    DATASET_SEED,
    DEFAULT_MODEL,
    FAST_MODEL,
    FAST_TARGETS,
    FAST_WIDTH,
    SHIPPED_DEPTH_BUNDLES,
    SPLIT,
    THREADS,
    TrainConfig,
    log,
    network_resolution,
)
from .reference_data import (
    Arrays,
    dataset_options,
    dataset_root,
    depth_images,
    ensure_dataset,
    heldout_test_split,
    load_arrays,
    reduce_frames,
    synthetic_test,
)
from .reference_install import (
    DEPTH_NOTE,
    FAST_NOTE,
    INT8_NOTE,
    REFERENCE_GRAPH,
    FastBundleError,
    attach_data_stats,
    default_data_stats,
    install_fast_bundle,
    install_int8_bundle,
    install_shipped_bundle,
    int8_bundle_path,
    network_input_int8,
    strip_node_metadata,
)
from .reference_training import calibration_data, make_bundles, record_depth_mapping, train

#: the recipe's names, importable from here as before (configs, data, training and installs
#: live in reference_configs.py, reference_data.py, reference_training.py, reference_install.py)
__all__ = ["ABOVE_RANGE_SHARE", "CONFIGS", "DATASET_N", "DATASET_SEED", "DEFAULT_MODEL", "FAST_MODEL", "FAST_TARGETS",
           "FAST_WIDTH", "SHIPPED_DEPTH_BUNDLES", "SPLIT", "THREADS", "TrainConfig", "log",
           "network_resolution", "Arrays", "dataset_options", "dataset_root", "depth_images",
           "ensure_dataset", "heldout_test_split", "load_arrays", "reduce_frames", "synthetic_test",
           "INT8_NOTE", "DEPTH_NOTE", "FAST_NOTE", "REFERENCE_GRAPH", "FastBundleError",
           "attach_data_stats", "default_data_stats", "install_int8_bundle", "install_fast_bundle",
           "install_shipped_bundle", "int8_bundle_path", "network_input_int8", "strip_node_metadata",
           "calibration_data",
           "make_bundles", "record_depth_mapping", "train", "main"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.reference", description=__doc__.split("\n\n")[0])
    ap.add_argument("--configs", default=",".join(CONFIGS), help=f"comma list of {', '.join(CONFIGS)}")
    ap.add_argument("--epochs", type=int, default=None, help="override every config's epochs")
    ap.add_argument("--retrain", action="store_true", help="ignore cached checkpoints")
    ap.add_argument("--int8-bundle", action="store_true",
                    help=f"install {DEFAULT_MODEL}'s int8 bundle as edge/models/rgbmod_int8")
    ap.add_argument("--network-input-int8", action="store_true",
                    help="rebuild edge/models/rgbmod_int8 as shipped: its graph of benchmarks/reference_graphs "
                         "cut at the network resolution (no training)")
    ap.add_argument("--shipped-bundles", action="store_true",
                    help="install the int8 bundles of " + ", ".join(SHIPPED_DEPTH_BUNDLES.values())
                    + " as edge/models/" + ", edge/models/".join(SHIPPED_DEPTH_BUNDLES))
    ap.add_argument("--fast-bundle", action="store_true",
                    help=f"install {FAST_MODEL}'s fp32 bundle as edge/models/default "
                         f"(train it: --configs {FAST_MODEL})")
    args = ap.parse_args(argv)
    if args.network_input_int8:
        network_input_int8()
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
    if args.int8_bundle:
        path = install_int8_bundle(cache_dir() / "models" / DEFAULT_MODEL / "int8")
        log(f"installed the int8 RGBmod at {path}")
    if args.shipped_bundles:
        for folder, name in SHIPPED_DEPTH_BUNDLES.items():
            path = install_shipped_bundle(folder, cache_dir() / "models" / name / "int8")
            log(f"installed {name} at {path}")
    if args.fast_bundle:
        path = install_fast_bundle(cache_dir() / "models" / FAST_MODEL)
        log(f"installed {FAST_MODEL} at {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
