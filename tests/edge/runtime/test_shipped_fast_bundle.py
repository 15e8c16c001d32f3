"""The shipped fast bundle (edge/models/fast): listed, verified, cheaper than the default by
construction (half the width, one residual block per stage: under a quarter of the default's
multiply-accumulates), within 0.03 RE of the default on the synthetic test split (both
manifests' ``error.vs_truth``, measured on the same 424 frames), and reading virtual-DIGIT
contact frames through ForceRuntime within the default's stated error (no timings: its
instructions per reading are counted by ``python -m benchmarks instructions``).
"""

import subprocess
import sys

import numpy as np
import pytest
from tactile_force.edge import ContactGate, OnnxForceModel, load_bundle, shipped_bundles
from tactile_force.edge.bundle.manifest import Precision
from tactile_force.edge.reading import Flags
from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor

from tests.conftest import ListSource


def test_listed_after_the_default_with_its_cheaper_architecture():
    found = shipped_bundles()
    assert list(found)[0] == "default" and "fast" in found
    fast, default = (load_bundle(found[n]).manifest for n in ("fast", "default"))
    # fp32: at 8-64 channels ORT's int8 convolution is mostly im2col copies, its fp32 one is cheaper
    assert fast.variant.value == "rgbmod" and fast.precision is Precision.FP32
    assert fast.architecture.blocks == [1, 1, 1, 1] and default.architecture.blocks == [2, 2, 2, 2]
    assert fast.architecture.network_input_hw == default.architecture.network_input_hw  # one reduction per frame
    assert fast.architecture.gmacs < 0.25 * default.architecture.gmacs
    assert fast.provenance.trained_on == "synthetic" and "SYNTHETIC" in fast.provenance.note
    assert fast.interval is not None and fast.data_stats is not None


def test_within_the_stated_margin_of_the_default_on_the_synthetic_test_split():
    pytest.importorskip("torch", reason="the recipe's targets (benchmarks/reference_configs.py) need the export extra")
    from tactile_force.benchmarks.reference_configs import FAST_TARGETS

    found = shipped_bundles()
    fast, default = (load_bundle(found[n]).manifest.error for n in ("fast", "default"))
    assert fast is not None and default is not None and fast.vs_truth is not None and default.vs_truth is not None
    assert fast.frames == default.frames  # the same 424 held-out frames
    assert all(e.data.startswith("synthetic test split (S1") for e in (fast, default))
    assert fast.vs_truth.re_mean <= default.vs_truth.re_mean + FAST_TARGETS["re_margin"]


def test_bundle_verify_passes():
    run = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "bundle", "verify",
                          str(shipped_bundles()["fast"])], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr


def test_reads_virtual_digit_contact_frames_like_the_default():
    from tactile_force.benchmarks.bench import contact_frames

    pool = contact_frames(40, seed=7)
    maes = {}
    for name in ("fast", "default"):
        gate = ContactGate()
        gate.capture_background(pool.background)
        rt = ForceRuntime([Sensor("s", ListSource(pool.rgb, pool.force), gate)],
                          OnnxForceModel(load_bundle(shipped_bundles()[name])), RuntimeOptions(deadline_ms=1e9))
        readings = []
        while not rt.finished:
            readings += rt.step()
        rt.close()
        assert len(readings) == len(pool.force)
        assert not any(r.flags & (Flags.NO_CONTACT | Flags.INVALID_INPUT) for r in readings)
        raw = np.array([r.raw_force_n for r in readings])
        assert np.isfinite(raw).all()
        maes[name] = float(np.mean(np.abs(raw - pool.force)))
    assert maes["fast"] < 2.5, maes
    assert maes["fast"] < maes["default"] + 1.0, maes


@pytest.mark.parametrize("flag", ["--bundle"])
def test_run_reads_with_it_from_the_cli(tmp_path, flag):
    out = tmp_path / "r.csv"
    run = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "run", "--source", "virtual",
                          "--max-frames", "60", flag, str(shipped_bundles()["fast"]), "--out", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert len(out.read_text().splitlines()) == 61
