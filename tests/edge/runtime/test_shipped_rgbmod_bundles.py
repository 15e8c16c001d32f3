"""The shipped RGBmod bundles: the default (edge/models/default, the fast fp32 RGBmod) listed first,
verified, cheaper than the int8 RGBmod (edge/models/rgbmod_int8) by construction (half the width, one
residual block per stage: under a quarter of its multiply-accumulates), within 0.03 RE of it on the
synthetic test split (both manifests' ``error.vs_truth``, measured on the same 424 frames), and
reading virtual-DIGIT contact frames through ForceRuntime like it (no timings: instructions per
reading are counted by ``python -m benchmarks instructions``, latency by ``tactile-force bench``).
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


def test_the_default_is_listed_first_with_the_cheaper_architecture():
    found = shipped_bundles()
    assert list(found)[0] == "default" and "rgbmod_int8" in found
    default, int8 = (load_bundle(found[n]).manifest for n in ("default", "rgbmod_int8"))
    # fp32: at 8-64 channels ORT's int8 convolution is mostly im2col copies, its fp32 one is cheaper
    assert default.variant.value == "rgbmod" and default.precision is Precision.FP32
    assert default.architecture.blocks == [1, 1, 1, 1] and int8.architecture.blocks == [2, 2, 2, 2]
    assert default.architecture.network_input_hw == int8.architecture.network_input_hw  # one reduction per frame
    assert default.architecture.gmacs < 0.25 * int8.architecture.gmacs
    assert default.provenance.trained_on == "synthetic" and "SYNTHETIC" in default.provenance.note
    assert default.interval is not None and default.data_stats is not None


def test_within_the_stated_margin_of_the_int8_rgbmod_on_the_synthetic_test_split():
    pytest.importorskip("torch", reason="the recipe's targets (benchmarks/reference_configs.py) need the export extra")
    from tactile_force.benchmarks.reference_configs import FAST_TARGETS

    found = shipped_bundles()
    default, int8 = (load_bundle(found[n]).manifest.error for n in ("default", "rgbmod_int8"))
    assert default is not None and int8 is not None and default.vs_truth is not None and int8.vs_truth is not None
    assert default.frames == int8.frames  # the same 424 held-out frames
    assert all(e.data.startswith("synthetic test split (S1") for e in (default, int8))
    assert default.vs_truth.re_mean <= int8.vs_truth.re_mean + FAST_TARGETS["re_margin"]


@pytest.mark.parametrize("name", ["default", "rgbmod_int8"])
def test_bundle_verify_passes(name):
    run = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "bundle", "verify",
                          str(shipped_bundles()[name])], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr


def test_reads_virtual_digit_contact_frames_like_the_int8_rgbmod():
    from tactile_force.benchmarks.bench import contact_frames

    pool = contact_frames(40, seed=7)
    maes = {}
    for name in ("default", "rgbmod_int8"):
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
    assert maes["default"] < 2.5, maes
    assert maes["default"] < maes["rgbmod_int8"] + 1.0, maes


@pytest.mark.parametrize("flag", ["--bundle"])
def test_run_reads_with_it_from_the_cli(tmp_path, flag):
    out = tmp_path / "r.csv"
    run = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "run", "--source", "virtual",
                          "--max-frames", "60", flag, str(shipped_bundles()["rgbmod_int8"]), "--out", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert len(out.read_text().splitlines()) == 61
