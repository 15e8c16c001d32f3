"""Issue 18, item 4: the default graph, node by node, and the variants that might pay.

    python -m benchmarks.graph_profile                 # table to stdout
    python -m benchmarks.graph_profile --runs 3000

Every variant is timed in one run, round-robin frame by frame in a rotating order (one intra-op thread,
sequential, batch 1, the same reduced 80x60 frames), as a ratio to the shipped graph with the
runtime's session options, so machine load cancels:

- session options: graph optimisation level (all / extended / basic), ``session.set_denormal_as_zero``,
  ``session.intra_op.allow_spinning`` 0 (one thread: no pool to spin, expected no change);
- NCHW uint8 input (the input Transpose dropped from the graph; the caller then transposes
  the reduced image, timed with it);
- fp32 instead of int8: the same weights dequantized, every Q/DQ pair removed.

The per-op table (onnxruntime's profiler, ``SessionOptions.enable_profiling``) of the shipped
and reference graphs is on docs/benchmarks/one_downscale.md. Needs onnx (the export extra)
for the graph variants.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
DEFAULT_DIR = REPO / "edge" / "models" / "default"


def bare_session(model: bytes | str | Path, level: str = "all", denormal_zero: bool = False,
                 spinning: bool | None = None):
    """A bare onnxruntime session as the benchmarks' yardstick: one intra-op and one inter-op
    thread, sequential, CPU provider, graph optimisation ``level`` ('all', 'extended', 'basic')."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.inter_op_num_threads = 1
    so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    so.graph_optimization_level = {"all": ort.GraphOptimizationLevel.ORT_ENABLE_ALL,
                                   "extended": ort.GraphOptimizationLevel.ORT_ENABLE_EXTENDED,
                                   "basic": ort.GraphOptimizationLevel.ORT_ENABLE_BASIC}[level]
    so.log_severity_level = 3
    if denormal_zero:
        so.add_session_config_entry("session.set_denormal_as_zero", "1")
    if spinning is not None:
        so.add_session_config_entry("session.intra_op.allow_spinning", "1" if spinning else "0")
    return ort.InferenceSession(model if isinstance(model, bytes) else str(model), so,
                                providers=["CPUExecutionProvider"])


def nchw_input(model_bytes: bytes) -> bytes:
    """The graph with an NCHW uint8 input: the NHWC -> NCHW Transpose after the input removed."""
    import onnx

    m = onnx.load_from_string(model_bytes)
    g = m.graph
    inp = g.input[0]
    tr = next(n for n in g.node if n.op_type == "Transpose" and n.input[0] == inp.name)
    for n in g.node:
        for i, x in enumerate(n.input):
            if x == tr.output[0]:
                n.input[i] = inp.name
    g.node.remove(tr)
    d = inp.type.tensor_type.shape.dim
    rows, cols, ch = d[1].dim_value, d[2].dim_value, d[3].dim_value
    d[1].dim_value, d[2].dim_value, d[3].dim_value = ch, rows, cols
    del g.value_info[:]
    onnx.checker.check_model(m)
    return m.SerializeToString()


def fp32_graph(model_bytes: bytes) -> bytes:
    """The QDQ graph as fp32: weights dequantized into float initializers, activation
    QuantizeLinear -> DequantizeLinear pairs replaced by the ReLU they implement (uint8, zero
    point 0) or nothing, a DequantizeLinear of the uint8 input replaced by Cast (scale 1 and
    zero point 0 only)."""
    import onnx
    from onnx import numpy_helper as nh

    m = onnx.load_from_string(model_bytes)
    g = m.graph
    inits = {t.name: t for t in g.initializer}
    producers = {o: n for n in g.node for o in n.output}

    def arr(name):
        return nh.to_array(inits[name])

    drop = []
    new_inits = []
    for n in list(g.node):
        if n.op_type != "DequantizeLinear":
            continue
        x, scale = n.input[0], arr(n.input[1])
        zp = arr(n.input[2]) if len(n.input) > 2 and n.input[2] else np.zeros_like(scale, dtype=np.int32)
        axis = next((a.i for a in n.attribute if a.name == "axis"), 1)
        if x in inits:
            q = arr(x).astype(np.float32)
            shape = [1] * q.ndim
            if np.ndim(scale):
                shape[axis] = -1
            w = (q - np.reshape(zp, shape).astype(np.float32)) * np.reshape(scale, shape).astype(np.float32)
            new_inits.append(nh.from_array(w.astype(np.float32), n.output[0]))
            drop.append(n)
        elif x in producers and producers[x].op_type == "QuantizeLinear":
            # a uint8 pair with zero point 0 clips at 0: the ReLU the quantizer absorbed
            q = producers[x]
            qzp = arr(q.input[2]) if len(q.input) > 2 and q.input[2] else np.zeros(1, np.uint8)
            relu = qzp.dtype == np.uint8 and int(np.max(qzp)) == 0
            n.op_type = "Relu" if relu else "Identity"
            del n.input[:]
            n.input.append(q.input[0])
            del n.attribute[:]
        else:  # the uint8 graph input
            if float(np.max(np.abs(scale - 1.0))) or int(np.max(np.abs(zp))):
                raise ValueError("input DequantizeLinear with scale != 1 or zero point != 0: not handled")
            n.op_type = "Cast"
            del n.input[1:]
            del n.attribute[:]
            n.attribute.append(onnx.helper.make_attribute("to", onnx.TensorProto.FLOAT))
    for n in drop:
        g.node.remove(n)
    used = {x for n in g.node for x in n.input}
    for n in [n for n in g.node if n.op_type == "QuantizeLinear" and not any(o in used for o in n.output)]:
        g.node.remove(n)
    used = {x for n in g.node for x in n.input}
    keep = [t for t in g.initializer if t.name in used]
    del g.initializer[:]
    g.initializer.extend(keep + [t for t in new_inits if t.name in used])
    del g.value_info[:]
    onnx.checker.check_model(m)
    return m.SerializeToString()


def variants(bundle: Path = DEFAULT_DIR):
    """(label, session, feed builder(reduced NHWC frame) -> feed dict, per-call prep or None)."""
    from tactile_force.edge import load_bundle

    b = load_bundle(bundle)
    raw = b.onnx_path.read_bytes()
    name = b.manifest.inputs[0].name
    nhwc = lambda x: {name: x}  # noqa: E731
    out = [("shipped: int8 QDQ, NHWC uint8 input, ORT_ENABLE_ALL", bare_session(raw), nhwc),
           ("graph optimisation level extended", bare_session(raw, "extended"), nhwc),
           ("graph optimisation level basic", bare_session(raw, "basic"), nhwc),
           ("session.set_denormal_as_zero = 1", bare_session(raw, denormal_zero=True), nhwc),
           ("session.intra_op.allow_spinning = 0", bare_session(raw, spinning=False), nhwc)]
    try:
        out.append(("NCHW uint8 input (Transpose out of the graph; np.transpose + copy timed with it)",
                    bare_session(nchw_input(raw)), lambda x: {name: np.ascontiguousarray(x.transpose(0, 3, 1, 2))}))
        out.append(("fp32 (same weights dequantized, no Q/DQ)", bare_session(fp32_graph(raw)), nhwc))
    except ImportError:
        pass
    return out


def measure(runs: int = 2000, bundle: Path = DEFAULT_DIR) -> list[list[object]]:
    """[[variant, p50 us, p99 us, p50 / shipped p50, max |force - shipped| N]] timed round-robin."""
    from tactile_force.edge import load_bundle
    from tactile_force.edge.gate.reduce import reduce_frames

    from .frames import frame_pool
    from .stats import percentiles

    m = load_bundle(bundle).manifest
    pool = frame_pool()
    frames = reduce_frames(pool.rgb, m.inputs[0].reduction)
    vs = variants(bundle)
    ref_out = [np.asarray(vs[0][1].run(None, vs[0][2](frames[i:i + 1]))[0]).reshape(-1) for i in range(len(frames))]
    diffs = []
    for _, sess, feed in vs:
        d = max(float(np.abs(np.asarray(sess.run(None, feed(frames[i:i + 1]))[0]).reshape(-1) - ref_out[i]).max())
                for i in range(len(frames)))
        diffs.append(d)
    times: list[list[float]] = [[] for _ in vs]
    for i in range(runs):
        x = frames[i % len(frames)][None]
        for r in range(len(vs)):  # rotate the order every round: no variant always follows the same one
            j = (i + r) % len(vs)
            _, sess, feed = vs[j]
            t0 = time.perf_counter_ns()
            sess.run(None, feed(x))
            times[j].append((time.perf_counter_ns() - t0) / 1e3)
    skip = min(100, runs // 10)
    base = percentiles(times[0][skip:]).p50
    rows = []
    for (label, _, _), t, d in zip(vs, times, diffs):
        p = percentiles(t[skip:])
        rows.append([label, p.p50, p.p99, p.p50 / base, d])
    return rows


def main(argv: list[str] | None = None) -> int:
    from .stats import markdown_table

    ap = argparse.ArgumentParser(prog="python -m benchmarks.graph_profile", description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=2000)
    ap.add_argument("--bundle", type=Path, default=DEFAULT_DIR)
    args = ap.parse_args(argv)
    print(markdown_table(["variant", "p50 us", "p99 us", "p50 / shipped", "max |diff| N"],
                         measure(args.runs, args.bundle)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
