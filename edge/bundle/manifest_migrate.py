"""Format-1 manifests (free-form dicts) migrated to the typed sections, for
:func:`~tactile_force.edge.bundle.manifest.manifest_from_json`."""

from __future__ import annotations

from typing import Any

from .manifest_format import FORMAT_VERSION
from .manifest_graph import Architecture, DepthRecord, Variant
from .manifest_records import DiffFigures, ErrorFigures, ErrorReport, Parity, Provenance, Quantization


def _pick(d: Any, cls: type, *, rename: dict[str, str] | None = None) -> dict[str, Any]:
    """Keep the keys of ``d`` that name fields of dataclass ``cls`` (format-1 migration)."""
    from dataclasses import fields

    if not isinstance(d, dict):
        raise TypeError(f"expected an object for {cls.__name__}, got {type(d).__name__}")
    names = {f.name for f in fields(cls)}
    ren: dict[str, str] = rename or {}
    out: dict[str, Any] = {}
    for key, value in d.items():
        name = ren.get(str(key), str(key))
        if name in names:
            out[name] = value
    return out


def migrate_v1(raw: dict[str, Any]) -> dict[str, Any]:
    """Format 1 (free-form dicts) -> format 2 (typed sections)."""
    out: dict[str, Any] = {k: raw[k] for k in ("variant", "precision", "name", "sha256", "onnx_file", "created_by")
                           if k in raw}
    out["format_version"] = FORMAT_VERSION
    inputs = raw.get("inputs")
    if isinstance(inputs, list) and all(isinstance(s, dict) for s in inputs):
        inputs = [{k: v for k, v in s.items() if k in ("name", "kind", "shape", "dtype", "layout", "colour_order",
                                                        "scaling")} for s in inputs]
    out["inputs"] = inputs  # anything else: the typed reader names the field
    output = raw.get("output")
    if isinstance(output, dict):
        out["output"] = {k: v for k, v in output.items() if k in ("name", "shape", "dtype", "unit")}
    elif output is not None:
        out["output"] = output
    out["preprocessing"] = raw.get("preprocessing_in_graph", [])
    arch = dict(raw.get("architecture") or {})
    depth = arch.pop("depth", None)
    out["architecture"] = _pick(arch, Architecture)
    if depth and out.get("variant") != Variant.RGBMOD.value:  # format 1 kept one in every architecture
        out["depth"] = _pick(depth, DepthRecord)
    if raw.get("quantization"):
        out["quantization"] = _pick(raw["quantization"], Quantization)
    if raw.get("parity"):
        out["parity"] = _pick(raw["parity"], Parity)
    err = raw.get("error") or {}
    if err:
        rep: dict[str, Any] = _pick(err, ErrorReport)
        truth = err.get("vs_ground_truth") or {}
        if truth.get("quantized"):
            rep["vs_truth"] = _pick(truth["quantized"], ErrorFigures)
            if truth.get("fp32"):
                rep["fp32_vs_truth"] = _pick(truth["fp32"], ErrorFigures)
        elif truth.get("fp32"):
            rep["vs_truth"] = _pick(truth["fp32"], ErrorFigures)
        if err.get("vs_fp32"):
            rep["vs_fp32"] = _pick(err["vs_fp32"], DiffFigures)
        out["error"] = rep
    prov = dict(raw.get("provenance") or {})
    known = _pick(prov, Provenance)
    extra = {k: v for k, v in prov.items() if k not in known and isinstance(v, (str, int, float, bool))}
    known.pop("extra", None)
    if extra:
        known["extra"] = extra
    out["provenance"] = known
    return out
