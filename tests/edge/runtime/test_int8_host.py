"""An int8 bundle gives the forces its graph defines on every host: where onnxruntime's fused int8 kernels
add in 16 bits (x86-64 without VNNI) and the weights use 8 bits, the graph runs unfused, as written."""

from __future__ import annotations

import numpy as np
import onnxruntime as ort
import pytest
from tactile_force.edge import ContactGate, ForceRuntime, OnnxForceModel, RuntimeOptions, Sensor, load_bundle
from tactile_force.edge.bundle.graph_facts import graph_facts
from tactile_force.edge.model import int8_host
from tactile_force.edge.model.onnx_model import session_options
from tactile_force.edge.scene import shipped_bundles

from tests.conftest import ListSource

INT8 = ["rgbmod_int8", "d", "rgbmod_d"]


def test_the_shipped_int8_graphs_use_8_bit_weights_and_the_fp32_one_none():
    for name in INT8:
        assert graph_facts(load_bundle(shipped_bundles()[name]).onnx_path).int8_weight_max > int8_host.SAFE_WEIGHT
    assert graph_facts(load_bundle(shipped_bundles()["default"]).onnx_path).int8_weight_max == 0


def test_unfused_exactly_where_8_bit_weights_meet_16_bit_sums(monkeypatch):
    monkeypatch.setattr(int8_host, "host_adds_in_16_bits", lambda: True)
    assert int8_host.exact_qdq_needed(127) and not int8_host.exact_qdq_needed(64) and not int8_host.exact_qdq_needed(0)
    monkeypatch.setattr(int8_host, "host_adds_in_16_bits", lambda: False)
    assert not int8_host.exact_qdq_needed(127)


@pytest.fixture(scope="module")
def contact_pool():
    from tactile_force.benchmarks.bench import contact_frames

    return contact_frames(64, seed=3)


@pytest.mark.parametrize("name", INT8)
def test_readings_equal_the_graph_run_as_written(name, contact_pool):
    """Whatever path this host takes, each reading is the graph's own force: the model's raw output equals
    a session that runs every QuantizeLinear / DequantizeLinear as written (the D bundle's fused int8
    kernels on an AVX2 host without VNNI were up to 6.4 N away)."""
    bundle = load_bundle(shipped_bundles()[name])
    gate = ContactGate()
    gate.capture_background(contact_pool.background)
    model = OnnxForceModel(bundle, calibrate=False)
    rt = ForceRuntime([Sensor("s", ListSource(contact_pool.rgb, contact_pool.force), gate)], model,
                      RuntimeOptions(deadline_ms=1e9))
    readings = []
    while not rt.finished:
        readings += rt.step()
    rt.close()
    assert model.unfused == int8_host.exact_qdq_needed(127)
    ref = ort.InferenceSession(str(bundle.onnx_path), session_options(1, exact_qdq=True),
                               providers=["CPUExecutionProvider"])
    from tactile_force.edge.bundle.manifest import InputKind
    from tactile_force.edge.frames import TimedFrame
    from tactile_force.edge.runtime import build_depth_stage
    from tactile_force.edge.runtime.gating import GateStep

    m = bundle.manifest
    depth = build_depth_stage(None, m) if m.input(InputKind.DEPTH) is not None else None
    gate2 = ContactGate()
    gate2.capture_background(contact_pool.background)
    got, want = [], []
    step = GateStep("s", gate2)
    for i, (frame, r) in enumerate(zip(contact_pool.rgb, readings)):
        g = step.run(TimedFrame(frame, i, i, arrival_ns=i))
        if g is None or not g.contact or not np.isfinite(r.raw_force_n):
            continue
        feed = {}
        for spec in m.inputs:
            if spec.kind is InputKind.DEPTH:
                assert depth is not None
                x = depth.process(g.reduced, g.reduced_mask, checked=True).depth
            else:
                x = g.reduced
            feed[spec.name] = np.ascontiguousarray(x.reshape(1, *x.shape))
        want.append(float(ref.run([m.output.name], feed)[0].ravel()[0]))
        got.append(r.raw_force_n)
    assert len(got) > 40
    diff = np.abs(np.array(got) - np.array(want))  # fused int8 on a VNNI host differs by requantization rounding
    assert diff.max() < 0.3 and diff.mean() < 0.05, (name, diff.max(), diff.mean())
