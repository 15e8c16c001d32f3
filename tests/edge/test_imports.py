"""Importing the runtime loads only what it uses (checked on sys.modules in a fresh interpreter)."""

from __future__ import annotations

import json
import subprocess
import sys

from tactile_force.edge.scene import default_bundle_path

HEAVY = ("tactile_force.edge.depth", "tactile_force.edge.synthetic", "tactile_force.export", "torch", "onnx",
         "depthai", "usb", "hid", "cyclonedds", "mcap", "pyudev", "matplotlib")


def _modules(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True).stdout
    return set(json.loads(out.strip().splitlines()[-1]))


def _loaded(mods: set[str], prefix: str) -> bool:
    return any(m == prefix or m.startswith(prefix + ".") for m in mods)


def test_import_edge_loads_only_the_contracts():
    mods = _modules("import tactile_force.edge")
    assert {"tactile_force.edge.bundle.manifest", "tactile_force.edge.bundle.store", "tactile_force.edge.reading"} <= mods
    for heavy in HEAVY + ("onnxruntime", "cv2", "tactile_force.edge.runtime.loop", "tactile_force.edge.scene"):
        assert not _loaded(mods, heavy), heavy


def test_an_rgbmod_runtime_never_loads_depth_synthetic_torch_or_devices(tmp_path):
    import cv2
    import numpy as np

    for i in range(3):
        cv2.imwrite(str(tmp_path / f"{i}.png"), np.full((320, 240, 3), 100, np.uint8))
    mods = _modules(
        "from tactile_force.edge import ForceRuntime, OnnxForceModel, Sensor, ContactGate, GateOptions, "
        "ReplayFolderSource\n"
        f"rt = ForceRuntime([Sensor('s', ReplayFolderSource({str(tmp_path)!r}), ContactGate(GateOptions()))], "
        f"OnnxForceModel({str(default_bundle_path())!r}))\n"
        "rt.run(); rt.close()")
    assert _loaded(mods, "onnxruntime") and _loaded(mods, "tactile_force.edge.runtime.loop")
    for heavy in HEAVY:
        assert not _loaded(mods, heavy), heavy


def test_the_bundle_ladder_has_its_own_module_and_its_old_path_warns():
    import importlib

    import pytest
    from tactile_force.edge.model import ladder, onnx_model

    for name in ("LadderChoice", "measure_p99_ms", "pick_from_ladder", "choose_bundle"):
        assert getattr(ladder, name).__module__ == "tactile_force.edge.model.ladder"
        assert not hasattr(onnx_model, name)
    with pytest.warns(DeprecationWarning, match=r"tactile_force\.edge\.inference moved to .*model\.ladder"):
        old = importlib.import_module("tactile_force.edge.inference")
    assert old.choose_bundle is ladder.choose_bundle and old.OnnxForceModel is onnx_model.OnnxForceModel


def test_only_the_cli_imports_benchmarks():
    """The robot-side package does not reach into benchmarks/ (a labelled replay lives in the runtime)."""
    import ast
    from pathlib import Path

    import tactile_force.edge

    root = Path(tactile_force.edge.__file__).resolve().parent
    found = []
    for path in sorted(root.rglob("*.py")):
        if "cli" in path.relative_to(root).parts[:1]:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            found += [f"{path.relative_to(root)}: {n}" for n in names
                      if n.split(".")[0] == "benchmarks" or n.startswith("tactile_force.benchmarks")]
    assert not found


def test_the_labelled_replay_is_the_runtime_s():
    from tactile_force.benchmarks import bench
    from tactile_force.edge.runtime.replay import replay_readings

    assert bench.replay_readings is replay_readings
