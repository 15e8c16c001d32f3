"""Bundle writes survive kill -9 in every window; graphs that break the frame contract are refused."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import textwrap

import pytest
from tactile_force.edge import BundleError, load_bundle
from tactile_force.edge.bundle.manifest import FrameReduction
from tactile_force.edge.bundle.store import stale_partials, write_bundle
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.scene import default_bundle_path

WRITER = textwrap.dedent("""
    import os, sys
    from tactile_force.edge.bundle import store as B
    dest, phase, exchange, tag = sys.argv[1], sys.argv[2], sys.argv[3] == "1", sys.argv[4]
    if not exchange:
        B._exchange = lambda a, b: False          # the two-rename path (filesystems without RENAME_EXCHANGE)
    B._phase = lambda name: os.kill(os.getpid(), 9) if name == phase else None
    src = B.load_bundle(sys.argv[5])
    src.manifest.name = tag
    B.write_bundle(dest, src.onnx_path.read_bytes(), src.manifest, overwrite=True)
""")


@pytest.fixture
def old_bundle(tmp_path):
    dest = tmp_path / "bundle"
    b = load_bundle(default_bundle_path())
    b.manifest.name = "old"
    write_bundle(dest, b.onnx_path.read_bytes(), b.manifest)
    return dest


@pytest.mark.parametrize("exchange, phase", [
    (True, "files-written"), (True, "exchanged"), (False, "files-written"), (False, "old-moved"), (True, "none"),
])
def test_kill_9_at_every_write_phase_leaves_a_complete_bundle(old_bundle, exchange, phase):
    run = subprocess.run([sys.executable, "-c", WRITER, str(old_bundle), phase, "1" if exchange else "0", "new",
                          str(default_bundle_path())], capture_output=True, text=True)
    killed = run.returncode == -signal.SIGKILL
    assert killed == (phase != "none"), run.stderr
    b = load_bundle(old_bundle)  # recovers an interrupted two-rename swap if needed
    expected = {"files-written": "old", "old-moved": "old", "exchanged": "new", "none": "new"}[phase]
    assert b.manifest.name == expected
    # the killed writer's leftovers are recognised, and the next write cleans them
    leftovers = stale_partials(old_bundle)
    assert all(p.name.endswith(".partial") for p in leftovers)
    write_bundle(old_bundle, b.onnx_path.read_bytes(), b.manifest, overwrite=True)
    assert stale_partials(old_bundle) == []
    assert sorted(p.name for p in old_bundle.parent.iterdir()) == ["bundle"]


def test_a_live_writer_partial_is_not_stale(tmp_path):
    part = tmp_path / ".bundle.abc.partial"
    part.mkdir()
    (part / ".writer-pid").write_text(str(__import__("os").getpid()))
    assert stale_partials(tmp_path / "bundle") == []
    (part / ".writer-pid").write_text("999999999")
    assert stale_partials(tmp_path / "bundle") == [part]


def _graph(shape, n_inputs=1, elem="uint8"):
    onnx = pytest.importorskip("onnx", reason="building test graphs needs the 'onnx' package (dev extra)")
    from onnx import TensorProto, helper

    et = {"uint8": TensorProto.UINT8, "float": TensorProto.FLOAT}[elem]
    inputs = [helper.make_tensor_value_info("rgb", et, shape)]
    nodes = [helper.make_node("Cast", ["rgb"], ["x"], to=TensorProto.FLOAT),
             helper.make_node("ReduceMean", ["x"], ["force_n"], axes=[1, 2, 3], keepdims=0)]
    if n_inputs == 2:
        inputs.append(helper.make_tensor_value_info("extra", TensorProto.UINT8, ["N", 4]))
    g = helper.make_graph(nodes, "g", inputs, [helper.make_tensor_value_info("force_n", TensorProto.FLOAT, ["N"])])
    m = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
    m.ir_version = 8
    return m.SerializeToString()


@pytest.mark.parametrize("shape, n_inputs, elem, message", [
    (["N", 240, 320, 3], 1, "uint8", "graph input 'rgb' is 240 x 320"),
    ([1, 320, 240, 3], 1, "uint8", "fixed batch of 1"),
    (["N", 320, 240, 1], 1, "uint8", r"graph input 'rgb' has 1 channel\(s\); the manifest calls it rgb"),
    (["N", 320, 240, 3], 2, "uint8", r"graph input 'extra' has dims \[None, 4\]"),
    (["N", 320, 240, 3], 1, "float", "the bundle contract is uint8"),
])
def test_graphs_that_break_the_frame_contract_are_refused_at_load(tmp_path, shape, n_inputs, elem, message):
    """Refused by write_bundle and, written by hand, by every load (the graph's facts read from
    the protobuf first, then ONNX Runtime's view of the graph) and by bundle verify."""
    import hashlib

    b = load_bundle(default_bundle_path())
    b.manifest.quantization = None
    b.manifest.precision = "fp32"
    b.manifest.__post_init__()
    # a full-resolution manifest (reduction none): the graph must take the 320x240 frame
    b.manifest.inputs[0].shape, b.manifest.inputs[0].reduction = [-1, 320, 240, 3], FrameReduction()
    b.manifest.architecture.input_scale, b.manifest.architecture.network_input_hw = 1.0, [320, 240]
    graph = _graph(shape, n_inputs, elem)
    dest = tmp_path / "b"
    with pytest.raises(BundleError, match=message):  # written through write_bundle ...
        write_bundle(dest, graph, b.manifest)
        OnnxForceModel(dest)
    shutil.rmtree(dest, ignore_errors=True)
    dest.mkdir()  # ... or by hand
    b.manifest.sha256 = hashlib.sha256(graph).hexdigest()
    (dest / "model.onnx").write_bytes(graph)
    (dest / "model.json").write_text(b.manifest.to_json())
    with pytest.raises(BundleError, match=message):
        OnnxForceModel(dest)
    run = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "bundle", "verify", str(dest)],
                         capture_output=True, text=True)
    assert run.returncode == 1 and "Traceback" not in run.stderr and "FAILED" in run.stderr


def test_hash_mismatch_and_missing_files(tmp_path):
    dest = tmp_path / "b"
    shutil.copytree(default_bundle_path(), dest)
    raw = json.loads((dest / "model.json").read_text())
    raw["sha256"] = "0" * 64
    (dest / "model.json").write_text(json.dumps(raw))
    with pytest.raises(BundleError, match="does not match the manifest"):
        load_bundle(dest)
    (dest / "model.onnx").unlink()
    with pytest.raises(BundleError, match="ONNX file missing"):
        load_bundle(dest)


def test_a_bundle_destination_that_is_a_link_is_refused_never_replaced(old_bundle, tmp_path):
    link = tmp_path / "link"
    link.symlink_to(old_bundle)
    b = load_bundle(old_bundle)
    with pytest.raises(BundleError, match="is a symbolic link"):
        write_bundle(link, b.onnx_path.read_bytes(), b.manifest, overwrite=True)
    assert link.is_symlink() and sorted(p.name for p in tmp_path.iterdir()) == ["bundle", "link"]


def test_a_bundle_being_written_is_claimed(old_bundle):
    from tactile_force.edge.files.claim import OutputBusy, OutputClaim

    b = load_bundle(old_bundle)
    with OutputClaim(old_bundle, "export"), pytest.raises(OutputBusy, match="is writing it now"):
        write_bundle(old_bundle, b.onnx_path.read_bytes(), b.manifest, overwrite=True)
    assert load_bundle(old_bundle).manifest.name == "old"
    assert sorted(p.name for p in old_bundle.parent.iterdir()) == ["bundle"]


def test_a_partial_that_is_not_a_bundle_writers_is_never_removed(old_bundle):
    other = old_bundle.parent / ".bundle.abc.partial"
    other.mkdir()
    (other / "notes.txt").write_text("not a bundle")
    b = load_bundle(old_bundle)
    write_bundle(old_bundle, b.onnx_path.read_bytes(), b.manifest, overwrite=True)
    assert (other / "notes.txt").read_text() == "not a bundle"
