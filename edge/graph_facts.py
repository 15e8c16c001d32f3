"""What an ONNX graph really contains, read from its protobuf bytes without the ``onnx`` package.

``tactile-force bundle verify`` runs on the robot, where only ONNX Runtime is installed. To
check a manifest's ``precision`` against the graph it needs the graph's op types and the
element types of its weights: both are plain protobuf fields, read here by a small wire-format
walker (varints and length-delimited fields only; a few milliseconds for a compact model).

ONNX protobuf fields used (onnx.proto3): ModelProto.graph = 7; GraphProto.node = 1,
GraphProto.initializer = 5; NodeProto.op_type = 4, NodeProto.attribute = 5;
AttributeProto.g = 6, AttributeProto.graphs = 11 (subgraphs of If/Loop);
TensorProto.data_type = 2 (1 float32, 10 float16, 2 uint8, 3 int8).
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from .errors import BundleError

#: TensorProto.DataType names of the element types the precision check looks at.
DATA_TYPES = {1: "float32", 2: "uint8", 3: "int8", 6: "int32", 7: "int64", 10: "float16", 11: "float64"}
#: Op types that make a graph a static int8 (QDQ or QOperator) graph.
STATIC_INT8_OPS = ("QuantizeLinear", "DequantizeLinear", "QLinearConv", "QLinearMatMul", "QLinearAdd",
                   "QLinearGlobalAveragePool", "QLinearConcat")
#: Op types of onnxruntime's dynamic quantization (weights int8, activations quantized per call).
DYNAMIC_INT8_OPS = ("DynamicQuantizeLinear", "ConvInteger", "MatMulInteger")


@dataclass
class GraphFacts:
    """Op type counts (``ops``) and initializer element type counts (``initializers``, by name
    from :data:`DATA_TYPES`, else ``type<N>``) of a graph and its subgraphs."""

    ops: Counter = field(default_factory=Counter)
    initializers: Counter = field(default_factory=Counter)


def _varint(buf: memoryview, i: int) -> tuple[int, int]:
    shift = value = 0
    while True:
        if i >= len(buf):
            raise ValueError("truncated varint")
        b = buf[i]
        i += 1
        value |= (b & 0x7F) << shift
        if b < 0x80:
            return value, i
        shift += 7
        if shift > 63:
            raise ValueError("varint too long")


def _fields(buf: memoryview):
    """(field number, wire type, value) of one message: int for varints, memoryview for
    length-delimited fields; fixed-width fields are skipped (value None)."""
    i, n = 0, len(buf)
    while i < n:
        key, i = _varint(buf, i)
        num, wt = key >> 3, key & 7
        if wt == 0:
            v, i = _varint(buf, i)
            yield num, wt, v
        elif wt == 2:
            ln, i = _varint(buf, i)
            if i + ln > n:
                raise ValueError("truncated field")
            yield num, wt, buf[i:i + ln]
            i += ln
        elif wt == 1:
            i += 8
            yield num, wt, None
        elif wt == 5:
            i += 4
            yield num, wt, None
        else:
            raise ValueError(f"unsupported wire type {wt}")


def _graph(buf: memoryview, facts: GraphFacts, depth: int = 0) -> None:
    if depth > 8:
        raise ValueError("subgraphs nested too deep")
    for num, wt, v in _fields(buf):
        if wt != 2:
            continue
        assert isinstance(v, memoryview)
        if num == 1:  # NodeProto
            for n2, w2, v2 in _fields(v):
                if w2 != 2:
                    continue
                assert isinstance(v2, memoryview)
                if n2 == 4:
                    facts.ops[bytes(v2).decode("utf-8", "replace")] += 1
                elif n2 == 5:  # AttributeProto: subgraphs
                    for n3, w3, v3 in _fields(v2):
                        if w3 == 2 and n3 in (6, 11):
                            assert isinstance(v3, memoryview)
                            _graph(v3, facts, depth + 1)
        elif num == 5:  # TensorProto initializer
            dtype = next((x for n2, w2, x in _fields(v) if n2 == 2 and w2 == 0), 0)
            facts.initializers[DATA_TYPES.get(int(dtype or 0), f"type{dtype}")] += 1


def graph_facts(onnx_path: str | os.PathLike) -> GraphFacts:
    """Op types and initializer element types of the ONNX model at ``onnx_path``.

    Raises :class:`BundleError` naming the file when it is not a readable ONNX protobuf."""
    p = Path(onnx_path)
    facts = GraphFacts()
    try:
        data = memoryview(p.read_bytes())
        found = False
        for num, wt, v in _fields(data):
            if num == 7 and wt == 2:
                assert isinstance(v, memoryview)
                _graph(v, facts)
                found = True
    except (OSError, ValueError) as exc:
        raise BundleError(f"{p}: cannot read the ONNX graph ({exc})") from None
    if not found:
        raise BundleError(f"{p}: no graph in this file; expected an ONNX model")
    return facts


def precision_problem(precision: str, facts: GraphFacts) -> str:
    """Why the graph does not hold a model of the manifest's ``precision``, or ""."""
    static = sorted(op for op in facts.ops if op in STATIC_INT8_OPS)
    dynamic = sorted(op for op in facts.ops if op in DYNAMIC_INT8_OPS)
    fp16 = facts.initializers.get("float16", 0)
    if precision == "int8-static":
        if not static:
            return ("the manifest says int8-static but the graph has no QuantizeLinear / DequantizeLinear / QLinear* "
                    f"node ({_ops(facts)}): it is not a statically quantized graph")
    elif precision == "int8-dynamic":
        if not (dynamic or static):
            return ("the manifest says int8-dynamic but the graph has no DynamicQuantizeLinear / ConvInteger / "
                    f"MatMulInteger / DequantizeLinear node ({_ops(facts)})")
    elif precision == "fp16":
        if not fp16:
            return (f"the manifest says fp16 but the graph has no float16 weights (initializers: "
                    f"{dict(facts.initializers)})")
    elif precision == "fp32":
        if static or dynamic:
            return f"the manifest says fp32 but the graph holds quantization nodes {static + dynamic}"
        if fp16:
            return f"the manifest says fp32 but the graph holds {fp16} float16 weight tensors"
    return ""


def _ops(facts: GraphFacts) -> str:
    top = ", ".join(f"{k} x{v}" for k, v in facts.ops.most_common(6))
    return f"ops: {top}" if top else "no ops"


__all__ = ["GraphFacts", "graph_facts", "precision_problem"]
