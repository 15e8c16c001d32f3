"""In-graph preprocessing alternatives, timed in ONNX Runtime (one thread) on a 320x240x3
uint8 frame -> 3 x 80 x 60 float network input (input scale 1/4). The exported graph's
current order (cast, NHWC->NCHW, BGR flip, /255, AveragePool) against cheaper equivalents:
transposing while still uint8, and folding the flip and the 1/255 into a fixed 4x4 stride-4
convolution (or into conv1's weights at export). Needs onnx (the export extra)."""

from __future__ import annotations

import time

import numpy as np


def _graphs(k: int = 4) -> dict[str, bytes]:
    import onnx
    from onnx import TensorProto as T
    from onnx import helper as h
    from onnx import numpy_helper as nh

    rows, cols = 320 // k, 240 // k

    def model(nodes, inits) -> bytes:
        g = h.make_graph(nodes, "pre", [h.make_tensor_value_info("x", T.UINT8, [1, 320, 240, 3])],
                         [h.make_tensor_value_info("y", T.FLOAT, [1, 3, rows, cols])], inits)
        m = h.make_model(g, opset_imports=[h.make_opsetid("", 18)])
        m.ir_version = 9
        onnx.checker.check_model(m)
        return m.SerializeToString()

    i64 = lambda v, n: nh.from_array(np.array(v, np.int64), n)  # noqa: E731
    pool = dict(kernel_shape=[k, k], strides=[k, k])
    w = np.zeros((3, 3, k, k), np.float32)
    for o in range(3):
        w[o, 2 - o] = 1.0 / (k * k) / 255.0  # output RGB channel o = input BGR channel 2-o
    return {
        "current: Cast, Transpose, Slice (BGR->RGB), Div 255, AveragePool": model([
            h.make_node("Cast", ["x"], ["a"], to=T.FLOAT), h.make_node("Transpose", ["a"], ["b"], perm=[0, 3, 1, 2]),
            h.make_node("Slice", ["b", "st", "en", "ax", "sp"], ["c"]), h.make_node("Div", ["c", "k"], ["d"]),
            h.make_node("AveragePool", ["d"], ["y"], **pool)],
            [i64([-1], "st"), i64([-(2**62)], "en"), i64([1], "ax"), i64([-1], "sp"),
             nh.from_array(np.array(255, np.float32), "k")]),
        "uint8 Transpose, Cast, AveragePool (flip and 1/255 folded into conv1)": model([
            h.make_node("Transpose", ["x"], ["a"], perm=[0, 3, 1, 2]), h.make_node("Cast", ["a"], ["b"], to=T.FLOAT),
            h.make_node("AveragePool", ["b"], ["y"], **pool)], []),
        "uint8 Transpose, Cast, fixed 4x4/4 Conv doing average + flip + 1/255": model([
            h.make_node("Transpose", ["x"], ["a"], perm=[0, 3, 1, 2]), h.make_node("Cast", ["a"], ["b"], to=T.FLOAT),
            h.make_node("Conv", ["b", "w"], ["y"], **pool)], [nh.from_array(w, "w")]),
    }


def measure_preprocessing(repeats: int = 1000) -> list[list[object]]:
    """[[graph, p50 us, p99 us, max abs diff to current], ...] plus OpenCV's INTER_AREA outside the graph."""
    import cv2
    import onnxruntime as ort

    from .stats import percentiles

    x = np.random.default_rng(0).integers(0, 256, (1, 320, 240, 3), dtype=np.uint8)
    rows, ref = [], None
    for name, b in _graphs().items():
        so = ort.SessionOptions()
        so.intra_op_num_threads = 1
        s = ort.InferenceSession(b, so, providers=["CPUExecutionProvider"])
        y = s.run(None, {"x": x})[0]
        if "Div" not in name and "Conv" not in name:
            y = y[:, ::-1] / 255.0 / 1.0  # same values once conv1 absorbs flip and scale
        ref = y if ref is None else ref
        for _ in range(30):
            s.run(None, {"x": x})
        t = []
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            s.run(None, {"x": x})
            t.append((time.perf_counter_ns() - t0) / 1e3)
        p = percentiles(t)
        rows.append([name, p.p50, p.p99, float(np.abs(y - ref).max())])
    cv2.setNumThreads(1)
    t = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        cv2.resize(x[0], (60, 80), interpolation=cv2.INTER_AREA)
        t.append((time.perf_counter_ns() - t0) / 1e3)
    p = percentiles(t)
    rows.append(["(reference) OpenCV INTER_AREA on uint8, outside the graph", p.p50, p.p99, None])
    return rows
