"""The embedded default bundle: intact, honest about its data, and as accurate as it says.

Re-measures its error on a freshly generated synthetic set of the held-out test indenters
(a seed the training never saw) and compares with the figure in its manifest.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from tactile_force.edge import AuthorsDataset, OnnxForceModel, default_bundle_path, load_bundle
from tactile_force.edge.bundle.store import sha256_file
from tactile_force.edge.data.metrics import error_stats
from tactile_force.edge.synthetic import DatasetOptions, generate_dataset, paper_split


@pytest.fixture(scope="module")
def bundle():
    path = default_bundle_path()
    if not (path / "model.onnx").is_file():
        pytest.skip(f"default bundle not built at {path} (python -m benchmarks.reference --fast-bundle)")
    return load_bundle(path)


def test_default_bundle_hash_matches_manifest(bundle):
    raw = json.loads((bundle.path / "model.json").read_text())
    assert sha256_file(bundle.onnx_path) == raw["sha256"]
    assert bundle.manifest.variant == "rgbmod"
    assert bundle.manifest.precision == "fp32"


def test_default_bundle_says_it_is_synthetic(bundle):
    note = bundle.manifest.provenance.note
    assert "SYNTHETIC" in note and "Replace" in note
    assert bundle.manifest.provenance.trained_on == "synthetic"


def test_default_bundle_error_on_fresh_synthetic_test_set(bundle, tmp_path):
    claimed = bundle.manifest.error.vs_truth
    split = paper_split("S1")
    generate_dataset(tmp_path / "fresh", DatasetOptions(n=96, seed=20261122, indenters=split.test, progress=False))
    ds = AuthorsDataset(tmp_path / "fresh")
    model = OnnxForceModel(bundle, threads=1)
    frames = [s.frame for s in ds]
    pred = np.concatenate([model.predict(np.stack(frames[i:i + 2])) for i in range(0, len(frames), 2)])
    fresh = error_stats(pred, ds.forces())
    # Same indenters, new poses and forces: the error must match the claim within sampling noise.
    print(f"fresh: {fresh}; manifest: RE {claimed.re_mean:.3f}, MAE {claimed.mae_mean:.3f} N")
    assert np.all(np.isfinite(pred))
    assert abs(fresh.re_mean - claimed.re_mean) < 0.05, (fresh, claimed)
    assert fresh.mae_mean < claimed.mae_mean + 0.4, (fresh, claimed)
