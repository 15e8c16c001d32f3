"""Training and export reduce frames exactly as the runtime does; compact exports
start at the network resolution."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="export tests need the export extra")

from tactile_force.edge import OnnxForceModel  # noqa: E402
from tactile_force.edge.bundle.manifest import FrameReduction, Reduction  # noqa: E402
from tactile_force.edge.gate.reduce import reduce_frames  # noqa: E402
from tactile_force.export import ExportOptions, ModelSpec, build_model, export_bundle  # noqa: E402
from tactile_force.export.preprocess import reduce_nchw  # noqa: E402


@pytest.mark.parametrize("reduction", [FrameReduction(Reduction.AREA, 4), FrameReduction(Reduction.AREA_2X_STEPS, 4),
                                       FrameReduction(Reduction.AREA_2X_STEPS, 8), FrameReduction(Reduction.AREA, 5)])
def test_torch_reduction_is_the_runtime_reduction_bit_for_bit(reduction):
    f = np.random.default_rng(3).integers(0, 256, (3, 320, 240, 3), dtype=np.uint8)
    want = reduce_frames(f, reduction)
    got = reduce_nchw(torch.from_numpy(f).permute(0, 3, 1, 2).float(), reduction).permute(0, 2, 3, 1)
    assert np.array_equal(got.to(torch.uint8).numpy(), want)


def test_compact_export_starts_at_the_network_resolution(tmp_path):
    torch.manual_seed(0)
    spec = ModelSpec("rgbmod", 0.125, 0.25)
    b = export_bundle(build_model("rgbmod", 0.125).eval(), tmp_path / "b",
                      ExportOptions(variant="rgbmod", width=0.125, input_scale=0.25))
    (s,) = b.manifest.inputs
    assert s.shape == [-1, 80, 60, 3] and s.reduction == FrameReduction(Reduction.AREA_2X_STEPS, 4)
    assert "AveragePool" not in b.onnx_path.read_bytes().decode("latin-1")
    assert b.manifest.parity.max_abs_diff_n <= 1e-4  # torch on full frames vs ORT on the reduced image
    m = OnnxForceModel(b)
    f = np.random.default_rng(0).integers(0, 256, (2, 320, 240, 3), dtype=np.uint8)
    assert np.array_equal(m.predict(f), m.predict_reduced(reduce_frames(f, s.reduction)))
    assert spec.input_scale == 0.25
