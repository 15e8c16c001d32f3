"""Build a Luxonis NN Archive (.tar.xz: config.json + compiled model) from our bundle.

The archive's config.json is derived from the bundle manifest: input names, shapes
(batch fixed to 1), dtype, layout, colour order and the fact that scaling (x / 255) is
inside the graph, so the device must feed raw uint8 pixels (mean 0, scale 1). The model
itself must already be compiled for the device: .blob / .superblob (RVC2) or .dlc (RVC4);
compiling needs the vendor toolchain (see docs/hardware.md).
"""

from __future__ import annotations

import io
import json
import os
import tarfile
from dataclasses import dataclass
from pathlib import Path

from tactile_force.edge.bundle.store import Bundle, load_bundle
from tactile_force.edge.errors import BundleError

#: compiled-model suffix -> RVC platform.
COMPILED_SUFFIXES = {".blob": "RVC2", ".superblob": "RVC2", ".dlc": "RVC4"}
CONFIG_VERSION = "1.0"


@dataclass(slots=True)
class NNArchiveInfo:
    """A written archive: path, the platform its model targets, and the config written."""

    path: Path
    platform: str
    config: dict


def _dai_type(colour_order: str, layout: str) -> str:
    if colour_order.upper() == "GRAY":
        return "GRAY8"
    planar = "p" if layout.upper() == "NCHW" else "i"
    return ("RGB888" if colour_order.upper() == "RGB" else "BGR888") + planar


def _precision(bundle_precision: str, platform: str) -> str:
    """Precision the compiled model runs at: RVC2 (MyriadX) always computes in float16."""
    if platform == "RVC2":
        return "float16"
    return {"fp32": "float32", "fp16": "float16"}.get(bundle_precision, "int8")


def archive_config(bundle: Bundle, model_file: str, platform: str = "RVC2") -> dict:
    """The NN Archive config.json (dict) for ``bundle`` around ``model_file``."""
    m = bundle.manifest
    inputs = []
    for spec in m.inputs:
        shape = [1 if d in (-1, None) else int(d) for d in spec.shape]
        colour = spec.colour_order if spec.kind != "depth" else "GRAY"
        inputs.append({
            "name": spec.name,
            "dtype": spec.dtype,
            "input_type": "image",
            "shape": shape,
            "layout": spec.layout,
            "preprocessing": {
                # Scaling is inside our graph: the device feeds raw 0..255 pixels.
                "mean": [0.0] * (1 if colour == "GRAY" else 3),
                "scale": [1.0] * (1 if colour == "GRAY" else 3),
                "reverse_channels": colour.upper() == "RGB",
                "interleaved_to_planar": spec.layout.upper() == "NCHW",
                "dai_type": _dai_type(colour, spec.layout),
            },
        })
    out = m.output
    return {
        "config_version": CONFIG_VERSION,
        "model": {
            "metadata": {"name": m.name or bundle.path.stem, "path": model_file,
                         "precision": _precision(m.precision, platform)},
            "inputs": inputs,
            "outputs": [{"name": out.name, "dtype": out.dtype,
                         "shape": [1 if d in (-1, None) else int(d) for d in out.shape],
                         "layout": "NC" if len(out.shape) == 2 else "N"}],
            "heads": [],
        },
    }


def build_nn_archive(bundle: Bundle | str | os.PathLike, compiled_model: str | os.PathLike,
                     dest: str | os.PathLike) -> NNArchiveInfo:
    """Write ``dest`` (.tar.xz) holding config.json and the compiled model; returns what was written.

    Raises BundleError when the compiled model is missing, empty, or not a .blob/.superblob/.dlc
    (an .onnx must first be compiled with the vendor toolchain).
    """
    if not isinstance(bundle, Bundle):
        bundle = load_bundle(bundle)
    model = Path(compiled_model)
    suffix = model.suffix.lower()
    if suffix not in COMPILED_SUFFIXES:
        raise BundleError(f"{model}: not a compiled OAK model (expected .blob/.superblob for RVC2 or .dlc for RVC4)"
                          + ("; compile the ONNX file with the vendor toolchain first (docs/hardware.md)"
                             if suffix == ".onnx" else ""))
    if not model.is_file():
        raise BundleError(f"{model}: compiled model not found")
    data = model.read_bytes()
    if not data:
        raise BundleError(f"{model}: compiled model is empty")
    dest = Path(dest)
    if not dest.name.endswith(".tar.xz"):
        raise BundleError(f"{dest}: NN Archive name must end in .tar.xz")
    config = archive_config(bundle, model.name, COMPILED_SUFFIXES[suffix])
    cfg_bytes = (json.dumps(config, indent=2) + "\n").encode()
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_name(f".{dest.name}.tmp")
    with tarfile.open(tmp, "w:xz") as tar:
        for name, payload in (("config.json", cfg_bytes), (model.name, data)):
            ti = tarfile.TarInfo(name)
            ti.size = len(payload)
            ti.mode = 0o644
            tar.addfile(ti, io.BytesIO(payload))
    os.replace(tmp, dest)
    return NNArchiveInfo(dest, COMPILED_SUFFIXES[suffix], config)
