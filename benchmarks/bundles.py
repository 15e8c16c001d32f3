"""Model bundles the docs pages measure: random-weight bundles for latency (built through the
public export_bundle / quantize_bundle, needs torch, cached) and the trained reference bundles
(``python -m benchmarks.reference``), both in the cache dir (:func:`benchmarks.harness.paths.cache_dir`)."""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

from .harness.frames import frame_pool
from .harness.latency import ModelConfig, parse_config
from .harness.paths import cache_dir

DEFAULT_CONFIG = "rgbmod-w0.25-s4"
PRECISIONS = ("fp32", "int8-static", "int8-dynamic", "fp16")


def trained_models_dir() -> Path:
    """Where the reference recipe keeps each config's checkpoint, record and bundles."""
    return cache_dir() / "models"


def latency_bundle(cfg: ModelConfig, precision: str, seed: int = 0) -> Path:
    """Path of a random-weight bundle of ``cfg`` at ``precision``, built on first use (needs
    torch). int8-static is calibrated on 32 virtual DIGIT frames in contact."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision {precision!r}; expected one of {PRECISIONS}")
    root = cache_dir() / "latency_bundles" / cfg.name
    out = root / precision
    if (out / "model.json").is_file():
        return out
    import torch
    from tactile_force.export import (
        ExportOptions,
        ForceNet,
        ModelSpec,
        QuantizeOptions,
        build_model,
        export_bundle,
        quantize_bundle,
    )

    pool = frame_pool()
    fp32 = root / "fp32"
    if not (fp32 / "model.json").is_file():
        torch.manual_seed(seed)
        net = ForceNet(build_model(cfg.variant, cfg.width, cfg.blocks),
                       ModelSpec(cfg.variant, cfg.width, 1.0 / cfg.k, cfg.blocks))
        with torch.no_grad():  # outputs around 8 N, inside the valid range, so the manifest's RE is defined
            [m for m in net.modules() if isinstance(m, torch.nn.Linear)][-1].bias.add_(8.0)
        why = f"nothing: random weights (torch seed {seed}), for latency only"
        export_bundle(net, fp32, ExportOptions(parity_data=pool.calibration(cfg.variant, 4), parity_tol_n=1e-3,
                                               name=f"{cfg.name}-random-fp32", overwrite=True, trained_on=why))
    if precision != "fp32":
        tmp = root / f"{precision}.partial"
        shutil.rmtree(tmp, ignore_errors=True)
        qo = QuantizeOptions(mode=precision, name=f"{cfg.name}-random-{precision}", overwrite=True)
        quantize_bundle(fp32, tmp, qo,
                        calibration=pool.calibration(cfg.variant, 32), eval_data=pool.calibration(cfg.variant, 8))
        shutil.rmtree(out, ignore_errors=True)
        tmp.rename(out)
    return out


@dataclass(frozen=True)
class TrainedModel:
    """A trained reference config: its record.json and whichever bundles exist."""

    config: ModelConfig
    root: Path
    record: dict
    bundles: dict[str, Path]


def trained_models() -> list[TrainedModel]:
    """Every <cache>/models/<config> with a record.json (the reference recipe's output)."""
    out: list[TrainedModel] = []
    root = trained_models_dir()
    if not root.is_dir():
        return out
    for d in sorted(root.iterdir()):
        rec = d / "record.json"
        if not rec.is_file():
            continue
        try:
            cfg = parse_config(d.name)
        except ValueError:
            continue
        bundles = {p: d / sub for p, sub in (("fp32", "fp32"), ("int8-static", "int8"))
                   if (d / sub / "model.json").is_file()}
        out.append(TrainedModel(cfg, d, json.loads(rec.read_text()), bundles))
    return out


def best_rgbmod_bundle() -> tuple[Path, str]:
    """The int8 RGBmod the latency page measures, and which it is: the trained config's int8 bundle,
    else the shipped edge/models/rgbmod_int8, else a random-weight bundle of that architecture."""
    from .reference_configs import int8_bundle_path

    int8 = int8_bundle_path()

    trained = trained_models_dir() / DEFAULT_CONFIG / "int8"
    if (trained / "model.json").is_file():
        return trained, f"trained {DEFAULT_CONFIG} int8 (benchmarks/cache/models/{DEFAULT_CONFIG}/int8)"
    if (int8 / "model.json").is_file():
        return int8, "shipped int8 RGBmod bundle (edge/models/rgbmod_int8)"
    cfg = parse_config(DEFAULT_CONFIG)
    return (latency_bundle(cfg, "int8-static"),
            f"RANDOM-weight {DEFAULT_CONFIG} int8 (not trained yet; same architecture and graph as the trained one)")
