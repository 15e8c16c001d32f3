"""What an ONNX graph really contains, read from its protobuf bytes without the ``onnx`` package.

``tactile-force bundle verify`` runs on the robot, where only ONNX Runtime is installed. To
check a manifest's claims against the graph it needs the graph's op types, the element types
of its weights and its inputs' shapes: all plain protobuf fields, read here by a small
wire-format walker (varints and length-delimited fields only; a few milliseconds for a
compact model).

- :func:`graph_precision`: the precision the graph holds (int8-static: QuantizeLinear on
  activations or QLinear* ops; int8-dynamic: DynamicQuantizeLinear / ConvInteger /
  MatMulInteger; fp16: float16 weights; fp32: none of these). ``bundle verify`` compares it
  with the manifest's ``precision``; ``tactile-force bench`` reports it.
- :func:`manifest_problems`: every manifest claim the graph can contradict: the precision, the
  architecture's width and residual blocks (:func:`architecture_problems`: the convolutions' count
  and channels),
  the network input size against ``architecture.input_scale`` / ``network_input_hw`` and the
  inputs' recorded ``reduction``, and the inputs against the variant (rgb / depth).

ONNX protobuf fields used (onnx.proto3): ModelProto.graph = 7; GraphProto.node = 1,
GraphProto.initializer = 5, GraphProto.input = 11; NodeProto.op_type = 4,
NodeProto.attribute = 5; AttributeProto.g = 6, AttributeProto.graphs = 11 (subgraphs of
If/Loop); TensorProto.data_type = 2 (1 float32, 10 float16, 2 uint8, 3 int8),
TensorProto.name = 8; ValueInfoProto.name = 1, .type = 2; TypeProto.tensor_type = 1;
TypeProto.Tensor.elem_type = 1, .shape = 2; TensorShapeProto.dim = 1;
Dimension.dim_value = 1, .dim_param = 2.
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import BundleError
from ..frames import FRAME_COLS, FRAME_ROWS

#: TensorProto.DataType names of the element types the precision check looks at.
DATA_TYPES = {1: "float32", 2: "uint8", 3: "int8", 6: "int32", 7: "int64", 10: "float16", 11: "float64"}
#: Op types that make a graph a static int8 graph: activations quantized with ranges fixed at
#: quantization time (QDQ: QuantizeLinear on activations; QOperator: QLinear*).
STATIC_INT8_OPS = ("QuantizeLinear", "QLinearConv", "QLinearMatMul", "QLinearAdd", "QLinearMul",
                   "QLinearGlobalAveragePool", "QLinearAveragePool", "QLinearConcat", "QLinearSigmoid",
                   "QLinearLeakyRelu")
#: Op types of onnxruntime's dynamic quantization (weights int8, activations quantized per call).
DYNAMIC_INT8_OPS = ("DynamicQuantizeLinear", "ConvInteger", "MatMulInteger", "DynamicQuantizeMatMul")
#: Op types that shrink an image inside a graph (a full-resolution input read at a smaller scale).
SHRINK_OPS = ("AveragePool", "Resize")
#: What :func:`graph_precision` calls a graph with both static and dynamic quantization nodes,
#: and one whose only quantization is DequantizeLinear of int8 weights (float activations).
INT8_MIXED = "int8-mixed"
INT8_WEIGHT_ONLY = "int8-weight-only"


@dataclass
class GraphInput:
    """One graph input (not an initializer): element type name and dims (None: symbolic, e.g.
    the dynamic batch)."""

    dtype: str
    dims: list[int | None]


@dataclass
class GraphFacts:
    """Op type counts (``ops``) and initializer element type counts (``initializers``, by name
    from :data:`DATA_TYPES`, else ``type<N>``) of a graph and its subgraphs, and the main
    graph's inputs (``inputs``: name -> :class:`GraphInput`, initializers left out)."""

    ops: Counter = field(default_factory=Counter)
    initializers: Counter = field(default_factory=Counter)
    inputs: dict[str, GraphInput] = field(default_factory=dict)
    #: dims of the 4-D initializers (convolution weights: out, in, kernel rows, kernel cols)
    kernels: list[tuple[int, ...]] = field(default_factory=list)
    #: the largest |value| of the int8 initializers (quantized weights; 0: none; 127 where not stored
    #: as raw bytes): above 63 the weights use all 8 bits (:mod:`tactile_force.edge.model.int8_host`)
    int8_weight_max: int = 0


def _varint(buf: memoryview, i: int) -> tuple[int, int]:
    if i < len(buf) and buf[i] < 0x80:  # one byte: most keys and lengths of a graph
        return buf[i], i + 1
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


def _sub(buf: memoryview, num: int) -> memoryview | None:
    """The last length-delimited field ``num`` of a message, or None."""
    out = None
    for n, wt, v in _fields(buf):
        if n == num and wt == 2:
            assert isinstance(v, memoryview)
            out = v
    return out


def _dims(tensor: memoryview) -> tuple[int, ...]:
    """TensorProto.dims (field 1, repeated int64: packed or one varint each)."""
    out: list[int] = []
    for n, wt, v in _fields(tensor):
        if n != 1:
            continue
        if wt == 0:
            out.append(int(v or 0))
        elif wt == 2:
            assert isinstance(v, memoryview)
            i = 0
            while i < len(v):
                d, i = _varint(v, i)
                out.append(d)
    return tuple(out)


def _value_info(buf: memoryview) -> tuple[str, GraphInput]:
    """(name, element type and dims) of a ValueInfoProto."""
    name_b = _sub(buf, 1)
    name = bytes(name_b).decode("utf-8", "replace") if name_b is not None else ""
    dtype, dims = "", []
    t = _sub(buf, 2)
    tensor = _sub(t, 1) if t is not None else None
    if tensor is not None:
        for n, wt, v in _fields(tensor):
            if n == 1 and wt == 0:
                dtype = DATA_TYPES.get(int(v or 0), f"type{v}")
            elif n == 2 and wt == 2:
                assert isinstance(v, memoryview)
                for n2, w2, d in _fields(v):
                    if n2 == 1 and w2 == 2:
                        assert isinstance(d, memoryview)
                        value = next((int(x or 0) for n3, w3, x in _fields(d) if n3 == 1 and w3 == 0), None)
                        dims.append(value)
    return name, GraphInput(dtype, dims)


def _graph(buf: memoryview, facts: GraphFacts, depth: int = 0) -> None:
    if depth > 8:
        raise ValueError("subgraphs nested too deep")
    inputs: dict[str, GraphInput] = {}
    weights: set[str] = set()
    for num, wt, v in _fields(buf):
        if wt != 2:
            continue
        assert isinstance(v, memoryview)
        if num == 11 and depth == 0:  # ValueInfoProto: a graph input
            name, gi = _value_info(v)
            inputs[name] = gi
        elif num == 1:  # NodeProto
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
            dims = _dims(v)
            if len(dims) == 4:
                facts.kernels.append(dims)
            if int(dtype or 0) == 3:  # int8
                raw = _sub(v, 9)  # TensorProto.raw_data
                top = int(np.abs(np.frombuffer(raw, np.int8).astype(np.int16)).max()) if raw is not None and len(raw) \
                    else 127
                facts.int8_weight_max = max(facts.int8_weight_max, top)
            name_b = _sub(v, 8)
            if name_b is not None:
                weights.add(bytes(name_b).decode("utf-8", "replace"))
    if depth == 0:  # older IR versions list initializers among the inputs too
        facts.inputs = {k: gi for k, gi in inputs.items() if k not in weights}


def graph_facts(onnx_path: str | os.PathLike) -> GraphFacts:
    """Op types and initializer element types of the ONNX model at ``onnx_path``.

    Raises :class:`BundleError` naming the file when it is not a readable ONNX protobuf."""
    p = Path(onnx_path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise BundleError(f"{p}: cannot read the ONNX graph ({exc.strerror})") from None
    return facts_of_bytes(data, p)


def facts_of_bytes(data: bytes, where: str | os.PathLike) -> GraphFacts:
    """:func:`graph_facts` of the serialized model ``data`` (``where``: the file, named in errors)."""
    facts = GraphFacts()
    try:
        found = False
        for num, wt, v in _fields(memoryview(data)):
            if num == 7 and wt == 2:
                assert isinstance(v, memoryview)
                _graph(v, facts)
                found = True
    except ValueError as exc:
        raise BundleError(f"{where}: cannot read the ONNX graph ({exc})") from None
    if not found:
        raise BundleError(f"{where}: no graph in this file; expected an ONNX model")
    return facts


#: Facts already read, by the graph's sha256 (the facts depend on the bytes only, and
#: :func:`~.store.load_bundle` has checked the sha256 before it asks): a model loaded again
#: (a runtime per sensor, a scene preflight then the build) is not parsed again.
_FACTS_BY_SHA256: dict[str, GraphFacts] = {}
_FACTS_KEPT = 16


def facts_by_sha256(digest: str, data: bytes, where: str | os.PathLike) -> GraphFacts:
    """:func:`facts_of_bytes` of ``data`` whose sha256 is ``digest``, read once per digest
    (the last :data:`_FACTS_KEPT` kept)."""
    facts = _FACTS_BY_SHA256.get(digest)
    if facts is None:
        facts = facts_of_bytes(data, where)
        if len(_FACTS_BY_SHA256) >= _FACTS_KEPT:
            _FACTS_BY_SHA256.pop(next(iter(_FACTS_BY_SHA256)))
        _FACTS_BY_SHA256[digest] = facts
    return facts


def bundle_facts(onnx_path: str | os.PathLike, digest: str) -> GraphFacts:
    """The facts of a loaded bundle's graph (``digest``: its sha256, checked by the loader): those read
    when it was loaded, else read now."""
    facts = _FACTS_BY_SHA256.get(digest)
    return facts if facts is not None else facts_by_sha256(digest, Path(onnx_path).read_bytes(), onnx_path)


def graph_precision(facts: GraphFacts) -> str:
    """The precision the graph holds, as a manifest's ``precision`` names it.

    ``int8-static``: activations quantized with fixed ranges (QuantizeLinear, or QLinear* ops);
    ``int8-dynamic``: DynamicQuantizeLinear / ConvInteger / MatMulInteger and no fixed-range
    activation quantization; ``fp16``: float16 weights and no quantization node; ``fp32``:
    none of these. Two values no manifest may claim: :data:`INT8_MIXED` (static and dynamic
    nodes together) and :data:`INT8_WEIGHT_ONLY` (DequantizeLinear of int8 weights only, float
    activations). ``bundle verify`` and ``tactile-force bench`` both use this.
    """
    static = any(op in facts.ops for op in STATIC_INT8_OPS)
    dynamic = any(op in facts.ops for op in DYNAMIC_INT8_OPS)
    if static and dynamic:
        return INT8_MIXED
    if static:
        return "int8-static"
    if dynamic:
        return "int8-dynamic"
    if "DequantizeLinear" in facts.ops:
        return INT8_WEIGHT_ONLY
    if facts.initializers.get("float16", 0):
        return "fp16"
    return "fp32"


def bundle_precision(onnx_path: str | os.PathLike) -> str:
    """:func:`graph_precision` of the ONNX model at ``onnx_path`` (BundleError when unreadable)."""
    return graph_precision(graph_facts(onnx_path))


def _evidence(found: str, facts: GraphFacts) -> str:
    """What in the graph makes it ``found`` (op and weight type counts)."""
    def count(names: tuple[str, ...]) -> str:
        return ", ".join(f"{op} x{facts.ops[op]}" for op in sorted(names) if op in facts.ops)

    if found in ("int8-static", "int8-dynamic", INT8_MIXED, INT8_WEIGHT_ONLY):
        return count((*STATIC_INT8_OPS, *DYNAMIC_INT8_OPS, "DequantizeLinear"))
    if found == "fp16":
        return f"{facts.initializers['float16']} float16 weight tensors, no quantization node"
    return ("no QuantizeLinear / DequantizeLinear / QLinear* / DynamicQuantizeLinear / ConvInteger / MatMulInteger "
            f"node and no float16 weights ({_ops(facts)}; initializers: {dict(facts.initializers)})")


def precision_problem(precision: str, facts: GraphFacts) -> str:
    """Why the graph does not hold a model of the manifest's ``precision`` (the graph's own
    precision, :func:`graph_precision`, and what shows it), or ""."""
    found = graph_precision(facts)
    if found == precision:
        return ""
    return f"precision: the manifest says {precision} but the graph is {found}: {_evidence(found, facts)}"


def input_problems(manifest, facts: GraphFacts) -> list[str]:  # manifest: Manifest
    """Where the graph's inputs contradict the manifest: their size against
    ``architecture.input_scale`` and ``network_input_hw`` and the inputs' recorded
    ``reduction``, and their kinds (3 channels: rgb, 1: depth) against the variant."""
    from .manifest import InputKind

    out: list[str] = []
    a = manifest.architecture
    scale = float(a.input_scale)
    rows, cols = FRAME_ROWS * scale, FRAME_COLS * scale
    want = (round(rows), round(cols))
    if abs(rows - want[0]) > 1e-6 or abs(cols - want[1]) > 1e-6:
        out.append(f"architecture.input_scale {scale:g}: the {FRAME_ROWS} x {FRAME_COLS} frame scaled by it is "
                   f"{rows:g} x {cols:g}, not a whole image")
    if [int(x) for x in a.network_input_hw] != list(want):
        out.append(f"architecture.network_input_hw {list(a.network_input_hw)} but architecture.input_scale "
                   f"{scale:g} makes the network read {want[0]} x {want[1]}")
    declared = {s.name: s for s in manifest.inputs}
    shrinks = any(op in facts.ops for op in SHRINK_OPS)
    kinds = set()
    for name, gi in facts.inputs.items():
        spec = declared.get(name)
        if len(gi.dims) != 4 or any(d is None for d in gi.dims[1:]):
            out.append(f"graph input {name!r} has dims {gi.dims}; expected (batch, rows, cols, channels)")
            continue
        r, c, ch = gi.dims[1], gi.dims[2], gi.dims[3]
        kind = {3: InputKind.RGB, 1: InputKind.DEPTH}.get(int(ch or 0))
        if kind is not None:
            kinds.add(kind)
        if spec is None:
            out.append(f"graph input {name!r} is not a manifest input (declared: {sorted(declared)})")
            continue
        if kind is not spec.kind:
            out.append(f"graph input {name!r} has {ch} channel(s); the manifest calls it {spec.kind.value} "
                       f"({spec.channels} channel(s))")
        if (r, c) != want and not ((r, c) == (FRAME_ROWS, FRAME_COLS) and scale < 1 and shrinks):
            out.append(f"architecture.input_scale {scale:g} says the network reads {want[0]} x {want[1]}, but graph "
                       f"input {name!r} is {r} x {c}" + (" and the graph shrinks no image inside (no AveragePool / "
                                                          "Resize)" if (r, c) == (FRAME_ROWS, FRAME_COLS) else ""))
        k = spec.reduction.factor
        if (r, c) != (FRAME_ROWS // k, FRAME_COLS // k):
            out.append(f"inputs[{name!r}].reduction {spec.reduction.method.value} x{k} makes "
                       f"{FRAME_ROWS // k} x {FRAME_COLS // k} images, but graph input {name!r} is {r} x {c}")
    v = manifest.variant
    need = {k for k, needed in ((InputKind.RGB, v.needs_rgb), (InputKind.DEPTH, v.needs_depth)) if needed}
    if facts.inputs and kinds != need:
        out.append(f"variant {v.value!r} reads {sorted(k.value for k in need)}, but the graph's inputs are "
                   f"{sorted(k.value for k in kinds)} ({', '.join(f'{n}: {g.dims}' for n, g in facts.inputs.items())})")
    return out


def architecture_problems(manifest, facts: GraphFacts) -> list[str]:  # manifest: Manifest
    """Where the graph's convolutions contradict ``architecture.width`` and ``architecture.blocks``
    (ResNet-18 family): each trunk (one 7 x 7 stem) has 4 + 2 x sum(blocks) convolutions (stem,
    two per residual block, a 1 x 1 shortcut at stages 2-4), its stem ``channels(width)[0]`` outputs
    and its convolutions the four stages' channel counts. A graph whose weights are not initializers
    shows neither: nothing said."""
    a = manifest.architecture
    if a.family != "resnet18":
        return []
    convs = [k for k in facts.kernels if k[0] >= 4 and k[2] == k[3] and k[2] in (1, 3, 7)]
    stems = [k for k in convs if k[2] == 7]
    if not stems:
        return []
    out: list[str] = []
    c = a.channels()
    per_trunk = 4 + 2 * sum(int(b) for b in a.blocks)
    if len(convs) != per_trunk * len(stems):
        found = (len(convs) // len(stems) - 4) / 2
        out.append(f"architecture.blocks {list(a.blocks)} makes {per_trunk} convolutions per trunk, but the graph "
                   f"has {len(convs)} in {len(stems)} trunk(s) ({found:g} residual blocks in all per trunk)")
    if any(s[0] != c[0] for s in stems) or max(k[0] for k in convs) != c[3]:
        out.append(f"architecture.width {a.width:g} makes stages of {list(c)} channels, but the graph's stem has "
                   f"{stems[0][0]} and its widest convolution {max(k[0] for k in convs)}")
    return out


def manifest_problems(manifest, facts: GraphFacts) -> list[str]:  # manifest: Manifest
    """Every manifest claim the graph contradicts (:func:`precision_problem`,
    :func:`input_problems`, :func:`architecture_problems`), one sentence each; [] when the graph
    agrees with all of them."""
    problem = precision_problem(manifest.precision.value, facts)
    return ([problem] if problem else []) + input_problems(manifest, facts) + architecture_problems(manifest, facts)


def _ops(facts: GraphFacts) -> str:
    top = ", ".join(f"{k} x{v}" for k, v in facts.ops.most_common(6))
    return f"ops: {top}" if top else "no ops"


__all__ = ["GraphFacts", "GraphInput", "architecture_problems", "bundle_facts", "bundle_precision", "facts_by_sha256",
           "facts_of_bytes", "graph_facts", "graph_precision", "input_problems", "manifest_problems",
           "precision_problem"]
