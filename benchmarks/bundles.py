"""Model bundles the benchmarks measure: random-weight bundles for latency (built through the
public export_bundle / quantize_bundle and cached) and the trained reference bundles."""

from __future__ import annotations

import json
import math
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .frames import CACHE, REPO, frame_pool

LATENCY_BUNDLES = CACHE / "latency_bundles"
TRAINED_MODELS = CACHE / "models"
DEFAULT_CONFIG = "rgbmod-w0.25-s4"
SHIPPED_DEFAULT = REPO / "edge" / "models" / "default"
PRECISIONS = ("fp32", "int8-static", "int8-dynamic", "fp16")


@dataclass(frozen=True)
class ModelConfig:
    """variant, width multiplier, input scale 1/k."""

    variant: str
    width: float
    k: int

    @property
    def name(self) -> str:
        return f"{self.variant}-w{self.width:g}-s{self.k}"  # as benchmarks.reference names it

    @property
    def label(self) -> str:
        size = "full res" if (self.width == 1 and self.k == 1) else f"w{self.width:g}, 1/{self.k}"
        return f"{VARIANT_LABEL[self.variant]} ({size})"


VARIANT_LABEL = {"rgbmod": "RGBmod", "d": "D", "dmod": "Dmod", "rgbmod+d": "RGBmod+D"}


def parse_config(name: str) -> ModelConfig:
    """'rgbmod-w0.25-s4' / 'rgbmod+d-w1-s1' -> ModelConfig."""
    try:
        v, w, s = name.rsplit("-", 2)
        return ModelConfig(v, float(w[1:]), int(s[1:]))
    except (ValueError, IndexError):
        raise ValueError(f"model config {name!r}: expected VARIANT-wWIDTH-sK, e.g. rgbmod-w0.25-s4") from None


def latency_bundle(cfg: ModelConfig, precision: str, seed: int = 0) -> Path:
    """Path of a random-weight bundle of ``cfg`` at ``precision``, built on first use (needs
    torch). int8-static is calibrated on 32 virtual DIGIT frames in contact."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision {precision!r}; expected one of {PRECISIONS}")
    root = LATENCY_BUNDLES / cfg.name
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
        net = ForceNet(build_model(cfg.variant, cfg.width), ModelSpec(cfg.variant, cfg.width, 1.0 / cfg.k))
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
    """Every benchmarks/cache/models/<config> with a record.json (the reference recipe's output)."""
    out = []
    if not TRAINED_MODELS.is_dir():
        return out
    for d in sorted(TRAINED_MODELS.iterdir()):
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


def bundle_re(path: Path) -> float:
    """Synthetic-test RE of a bundle as its manifest records it (nan when absent)."""
    from tactile_force.edge.bundle.store import read_manifest
    from tactile_force.edge.errors import BundleError

    try:
        score = read_manifest(path / "model.json").error_score()
    except BundleError:
        return float("nan")
    return score if math.isfinite(score) else float("nan")


def rgbmod_candidates() -> list[tuple[Path, str, float]]:
    """(bundle, description, synthetic-test RE) of every trained int8 RGBmod, most accurate
    first; without trained ones, the single :func:`best_rgbmod_bundle` fallback."""
    out = [(t.bundles["int8-static"], f"trained {t.config.name} int8", bundle_re(t.bundles["int8-static"]))
           for t in trained_models() if t.config.variant == "rgbmod" and "int8-static" in t.bundles]
    if not out:
        path, which = best_rgbmod_bundle()
        return [(path, which, bundle_re(path))]
    return sorted(out, key=lambda c: (not np.isfinite(c[2]), c[2]))


def trained_int8(variant: str, config: ModelConfig) -> Path | None:
    """The trained int8 bundle of ``config`` when the reference recipe made one."""
    p = TRAINED_MODELS / config.name / "int8"
    return p if config.variant == variant and (p / "model.json").is_file() else None


def best_rgbmod_bundle() -> tuple[Path, str]:
    """The bundle --check measures, and which it is: the trained default config's int8 bundle,
    else the shipped edge/models/default, else a random-weight bundle of that architecture."""
    trained = TRAINED_MODELS / DEFAULT_CONFIG / "int8"
    if (trained / "model.json").is_file():
        return trained, f"trained {DEFAULT_CONFIG} int8 (benchmarks/cache/models/{DEFAULT_CONFIG}/int8)"
    if (SHIPPED_DEFAULT / "model.json").is_file():
        return SHIPPED_DEFAULT, "shipped default bundle (edge/models/default)"
    cfg = parse_config(DEFAULT_CONFIG)
    return (latency_bundle(cfg, "int8-static"),
            f"RANDOM-weight {DEFAULT_CONFIG} int8 (not trained yet; same architecture and graph as the trained one)")
