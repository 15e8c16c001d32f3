"""Graphs that start at the network resolution: exact surgery on full-resolution compact graphs.

A format-2 compact bundle's graph takes the 320 x 240 frame and shrinks it inside the graph
(``Transpose`` uint8 NHWC -> NCHW, ``Cast`` to float, ``AveragePool`` k x k stride k; in an
int8 graph then ``QuantizeLinear`` of the pool's output). :func:`start_at_network_input`
removes that shrink: the graph input becomes the reduced (N, 320/k, 240/k, C) uint8 image,
the same weights follow. When the pool's output was quantized with scale 1 and zero point 0
(the int8 default bundle: an average of uint8 values quantized to uint8 is its rounding),
the Cast and the QuantizeLinear go too, and the uint8 input feeds the first DequantizeLinear
directly: fed the exact k x k average rounded half to even (reduction ``area``) the new graph
gives the old graph's forces to the last bit. Needs onnx (the export extra).

:func:`network_input_bundle` applies it to a bundle and writes a format-3 bundle recording the
reduction the runtime must use.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import numpy as np
from tactile_force.edge.bundle.manifest import FrameReduction, InputSpec, Reduction
from tactile_force.edge.bundle.store import Bundle, load_bundle, write_bundle
from tactile_force.edge.errors import TactileForceError
from tactile_force.edge.frames import FRAME_COLS, FRAME_ROWS

from .graph import _onnx, op_counts


class SurgeryError(TactileForceError):
    """The graph does not have the in-graph shrink this surgery removes."""


def _consumers(graph, name: str) -> list:
    return [n for n in graph.node if name in n.input]


def _init(graph, name: str) -> np.ndarray | None:
    onnx = _onnx()
    for t in graph.initializer:
        if t.name == name:
            return onnx.numpy_helper.to_array(t)
    return None


def start_at_network_input(model_bytes: bytes, factor: int) -> tuple[bytes, list[str]]:
    """Remove the in-graph k x k shrink in front of every graph input.

    Parameters
    ----------
    model_bytes
        A serialized graph whose inputs are uint8 NHWC (batch, 320, 240, C), each followed by
        Transpose -> Cast -> AveragePool(k, stride k).
    factor
        k, the reduction factor the AveragePool implements (4: 320 x 240 -> 80 x 60).

    Returns
    -------
    (bytes, steps)
        The new graph (inputs uint8 NHWC (batch, 320/k, 240/k, C)) and what its preprocessing
        is now, in order (for the manifest's ``preprocessing``).

    Raises
    ------
    SurgeryError
        When an input is not followed by that chain (another exporter's graph, or one already
        at the network resolution).
    """
    onnx = _onnx()
    model = onnx.load_from_string(model_bytes)
    g = model.graph
    k = int(factor)
    if k < 2:
        raise SurgeryError(f"factor {factor}: the surgery removes a k x k shrink, k >= 2")
    steps: list[str] = []
    for inp in g.input:
        dims = inp.type.tensor_type.shape.dim
        if inp.type.tensor_type.elem_type != onnx.TensorProto.UINT8 or len(dims) != 4 \
                or [d.dim_value for d in dims[1:3]] != [FRAME_ROWS, FRAME_COLS]:
            raise SurgeryError(f"graph input {inp.name!r}: expected uint8 (batch, {FRAME_ROWS}, {FRAME_COLS}, C)")
        chain = []
        name = inp.name
        for op in ("Transpose", "Cast", "AveragePool"):
            nxt = _consumers(g, name)
            if len(nxt) != 1 or nxt[0].op_type != op:
                raise SurgeryError(f"graph input {inp.name!r}: expected Transpose -> Cast -> AveragePool after it, "
                                   f"found {[n.op_type for n in nxt]} after {name!r}")
            chain.append(nxt[0])
            name = nxt[0].output[0]
        transpose, cast, pool = chain
        attrs = {a.name: onnx.helper.get_attribute_value(a) for a in pool.attribute}
        if list(attrs.get("kernel_shape", [])) != [k, k] or list(attrs.get("strides", [])) != [k, k] \
                or any(attrs.get("pads", [0]) or [0]):
            raise SurgeryError(f"{pool.name}: AveragePool {attrs}; expected a {k}x{k} stride-{k} pool without padding")
        perm = next(list(onnx.helper.get_attribute_value(a)) for a in transpose.attribute if a.name == "perm")
        if perm != [0, 3, 1, 2]:
            raise SurgeryError(f"{transpose.name}: perm {perm}; expected NHWC -> NCHW [0, 3, 1, 2]")
        dims[1].dim_value, dims[2].dim_value = FRAME_ROWS // k, FRAME_COLS // k
        pool_out = pool.output[0]
        users = _consumers(g, pool_out)
        q = users[0] if len(users) == 1 and users[0].op_type == "QuantizeLinear" else None
        exact_q = False
        if q is not None:
            scale, zp = _init(g, q.input[1]), _init(g, q.input[2]) if len(q.input) > 2 else None
            exact_q = (scale is not None and zp is not None and zp.dtype == np.uint8 and float(scale) == 1.0
                       and int(zp) == 0)
        if exact_q:
            # uint8 in [0, 255] quantized with scale 1 / zero point 0 is itself: the Transpose's
            # uint8 output replaces the QuantizeLinear's, Cast, pool and quantizer go.
            assert q is not None
            for n in _consumers(g, q.output[0]):
                for i, x in enumerate(n.input):
                    if x == q.output[0]:
                        n.input[i] = transpose.output[0]
            for n in (cast, pool, q):
                g.node.remove(n)
            steps += [f"{inp.name}: NHWC -> NCHW (uint8), fed to the first DequantizeLinear "
                      "(the input quantizer had scale 1, zero point 0: uint8 is the quantized value)"]
        else:
            for n in users:
                for i, x in enumerate(n.input):
                    if x == pool_out:
                        n.input[i] = cast.output[0]
            g.node.remove(pool)
            steps += [f"{inp.name}: NHWC -> NCHW (uint8)", f"{inp.name}: cast uint8 -> float32"]
    del g.value_info[:]  # shapes recorded for the full-resolution tensors; ORT infers them again
    onnx.checker.check_model(model)
    return model.SerializeToString(), steps


def network_input_bundle(src: Bundle | str | os.PathLike, dest: str | os.PathLike,
                         reduction: FrameReduction, overwrite: bool = False, name: str = "") -> Bundle:
    """Write ``src`` (a format-2 compact bundle, reduction ``none``) as a bundle whose graph starts
    at the network resolution, with ``reduction`` recorded on every input.

    Parameters
    ----------
    src, dest
        The bundle to convert and where to write the new one.
    reduction
        How the runtime reduces frames for it (factor = the graph's AveragePool size).
    overwrite
        Replace ``dest`` if it exists.
    name
        The new manifest's name (default: the source's).

    Returns
    -------
    Bundle
        The written, verified bundle. Same weights; error figures are copied from the source
        and must be re-measured when the reduction is not ``area`` (exact).
    """
    bundle = src if isinstance(src, Bundle) else load_bundle(src)
    m = bundle.manifest
    if any(s.reduction.method is not Reduction.NONE for s in m.inputs):
        raise SurgeryError(f"{bundle.path}: the graph already starts at the network resolution")
    reduction.check()
    new_bytes, steps = start_at_network_input(bundle.onnx_path.read_bytes(), reduction.factor)
    rows, cols = FRAME_ROWS // reduction.factor, FRAME_COLS // reduction.factor
    inputs = [InputSpec(name=s.name, kind=s.kind, shape=[-1, rows, cols, s.channels], dtype=s.dtype,
                        layout=s.layout, colour_order=s.colour_order, scaling=s.scaling,
                        reduction=FrameReduction(reduction.method, reduction.factor)) for s in m.inputs]
    kept = [st for st in m.preprocessing if "folded into conv1" in st]
    pre = [f"frame {FRAME_ROWS}x{FRAME_COLS} -> {rows}x{cols} outside the graph, once per frame: "
           f"{reduction.method.value} x{reduction.factor} (edge/gate/reduce.py)", *steps, *kept]
    onnx = _onnx()
    manifest = replace(m, inputs=inputs, preprocessing=pre, sha256="")
    if manifest.quantization is not None:
        manifest.quantization = replace(manifest.quantization,
                                        op_counts=dict(op_counts(onnx.load_from_string(new_bytes))))
    manifest.architecture = replace(m.architecture, network_input_hw=[rows, cols])
    if name:
        manifest.name = name
    return write_bundle(Path(dest), new_bytes, manifest, overwrite=overwrite)
