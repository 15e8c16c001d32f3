"""Small ONNX graph utilities shared by export and quantization."""

from __future__ import annotations

import os
import tempfile
from collections import Counter
from pathlib import Path

from tactile_force.edge.errors import require


def _onnx():
    return require("onnx", "export", "Editing ONNX graphs")


def name_nodes(model) -> int:
    """Give every unnamed node a unique name '<op>_<i>' (in place); returns how many were named.

    onnxruntime's quantizer matches nodes_to_exclude by name, and an empty name would
    match every unnamed node, so names must exist before anything is excluded.
    """
    taken = {n.name for n in model.graph.node if n.name}
    named = 0
    for i, node in enumerate(model.graph.node):
        if node.name:
            continue
        name = f"{node.op_type}_{i}"
        while name in taken:
            name += "_"
        node.name = name
        taken.add(name)
        named += 1
    return named


def producer_chain(model, output_name: str, ops: tuple[str, ...] = ("Gemm", "MatMul")) -> list[str]:
    """Names of the nodes from graph output ``output_name`` back to (and including) the first
    node whose op is in ``ops``: the final linear layer plus the reshapes after it."""
    producers = {o: n for n in model.graph.node for o in n.output}
    chain, name = [], output_name
    while name in producers:
        node = producers[name]
        chain.append(node.name)
        if node.op_type in ops:
            return chain
        data_inputs = [i for i in node.input if i in producers]
        if not data_inputs:
            break
        name = data_inputs[0]
    raise ValueError(f"no {'/'.join(ops)} node feeds graph output {output_name!r}")


def op_counts(model) -> Counter:
    """Count of nodes per op type."""
    return Counter(n.op_type for n in model.graph.node)


def ort_optimized_ops(model_bytes: bytes, level: str = "extended") -> Counter:
    """Op counts of the graph onnxruntime actually runs on the CPU after its graph optimisations
    (QDQ 'DequantizeLinear -> Conv -> QuantizeLinear' groups become QLinearConv here)."""
    import onnxruntime as ort

    onnx = _onnx()
    levels = {"basic": ort.GraphOptimizationLevel.ORT_ENABLE_BASIC,
              "extended": ort.GraphOptimizationLevel.ORT_ENABLE_EXTENDED,
              "all": ort.GraphOptimizationLevel.ORT_ENABLE_ALL}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "optimized.onnx"
        so = ort.SessionOptions()
        so.graph_optimization_level = levels[level]
        so.optimized_model_filepath = os.fspath(out)
        so.intra_op_num_threads = 1
        ort.InferenceSession(model_bytes, so, providers=["CPUExecutionProvider"])
        return op_counts(onnx.load(os.fspath(out)))
