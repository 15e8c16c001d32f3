"""Multiply-accumulate count of an ONNX graph (convolutions and matrix products), batch 1."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from tactile_force.edge.errors import require

_CONV = ("Conv", "ConvInteger", "QLinearConv")
_MATMUL = ("Gemm", "MatMul", "MatMulInteger", "QLinearMatMul")


@dataclass
class MacCount:
    """MACs per frame: total, convolutions, matrix products; per op type."""

    total: int
    conv: int
    matmul: int
    by_op: dict[str, int] = field(default_factory=dict)

    @property
    def gmacs(self) -> float:
        return self.total / 1e9


def count_macs(model, batch: int = 1) -> MacCount:
    """Count MACs of an ONNX model (ModelProto or path) for ``batch`` frames.

    Conv: prod(output shape) * Cin/group * kh * kw. Gemm/MatMul: prod(output) * K.
    """
    onnx = require("onnx", "export", "Counting MACs")
    m = onnx.load(os.fspath(model)) if isinstance(model, (str, os.PathLike)) else onnx.ModelProto.FromString(
        model.SerializeToString())
    for inp in m.graph.input:
        dims = inp.type.tensor_type.shape.dim
        if dims and not dims[0].dim_value:
            dims[0].ClearField("dim_param")
            dims[0].dim_value = batch
    del m.graph.value_info[:]
    m = onnx.shape_inference.infer_shapes(m, data_prop=True)
    shapes: dict[str, list[int]] = {t.name: list(t.dims) for t in m.graph.initializer}
    for vi in list(m.graph.value_info) + list(m.graph.input) + list(m.graph.output):
        dims = vi.type.tensor_type.shape.dim
        if all(d.dim_value > 0 for d in dims):
            shapes[vi.name] = [d.dim_value for d in dims]
    for node in m.graph.node:
        if node.op_type == "Constant":
            for a in node.attribute:
                if a.name == "value":
                    shapes[node.output[0]] = list(a.t.dims)
    by_op: dict[str, int] = {}

    def prod(xs: list[int]) -> int:
        out = 1
        for x in xs:
            out *= int(x)
        return out

    for node in m.graph.node:
        op = node.op_type
        if op in _CONV:
            w_name = node.input[3] if op == "QLinearConv" else node.input[1]
            out, w = shapes.get(node.output[0]), shapes.get(w_name)
            if out is None or w is None:
                raise ValueError(f"count_macs: cannot infer shapes around {op} node {node.name!r}")
            macs = prod(out) * prod(w[1:])
        elif op in _MATMUL:
            a = shapes.get(node.input[0])
            out = shapes.get(node.output[0])
            if out is None or a is None:
                raise ValueError(f"count_macs: cannot infer shapes around {op} node {node.name!r}")
            trans_a = any(at.name == "transA" and at.i for at in node.attribute)
            k = a[-2] if (op == "Gemm" and trans_a) else a[-1]
            macs = prod(out) * k
        else:
            continue
        by_op[op] = by_op.get(op, 0) + macs
    conv = sum(v for k, v in by_op.items() if k in _CONV)
    mm = sum(v for k, v in by_op.items() if k in _MATMUL)
    return MacCount(total=conv + mm, conv=conv, matmul=mm, by_op=by_op)
