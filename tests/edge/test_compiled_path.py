"""Nothing compiles on the reading path (edge/compiled_path.py): a runtime's constructor and its first
``step()`` never run numba's compiler, whatever its cache holds; the robot-side path never imports
numba; readings are the same on both paths; and a missing extra is named before any work."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from tactile_force.edge import compiled_path
from tactile_force.edge.errors import MissingExtraError, OptionsError

from tests.conftest import REPO, compiled_kernels

#: a process that builds a runtime per shipped bundle and takes its first readings, counting numba's
#: compiles (begun and finished) from before the runtime is made; prints what it saw as JSON
_FIRST_READING = textwrap.dedent("""
    import json, sys
    from tactile_force.edge import (ContactGate, ForceRuntime, OnnxForceModel, RuntimeOptions, Sensor,
                                    VirtualDigitSource, compiled_path, shipped_bundles)
    seen = {"begun": 0, "finished": 0}
    if compiled_path.installed() and compiled_path.kernel_mode().value != "off":  # 'off' must not load numba
        from numba.core import event

        class Count(event.Listener):
            def on_start(self, ev):
                seen["begun"] += 1

            def on_end(self, ev):
                seen["finished"] += 0 if ev.is_failed else 1

        event.register("numba:compile", Count())
    readings = {}
    for name in ("default", "d"):
        rt = ForceRuntime([Sensor("s", VirtualDigitSource(seed=0, n_grasps=1), ContactGate())],
                          OnnxForceModel(shipped_bundles()[name], threads=1), RuntimeOptions(deadline_ms=1000.0))
        readings[name] = [r.force_n for _ in range(3) for r in rt.step()]
        rt.close()
    compiled = 0  # machine code the kernels' dispatchers hold (compiled here or loaded from the cache)
    for mod in compiled_path.KIND_MODULES.values():
        for f in vars(sys.modules[mod]).values() if mod in sys.modules else ():
            compiled += len(getattr(f, "overloads", ()))
    print(json.dumps({"seen": seen, "compiled": compiled, "numba": "numba" in sys.modules,
                      "path": compiled_path.describe(), "gate": compiled_path.gate_kernels() is not None,
                      "depth": compiled_path.depth_kernels() is not None, "readings": readings}))
""")


def _first_reading(env: dict[str, str]) -> tuple[dict, str]:
    full = {**os.environ, **env}
    full.pop("NUMBA_CACHE_DIR", None)
    p = subprocess.run([sys.executable, "-c", _FIRST_READING], capture_output=True, text=True, env=full, cwd=REPO,
                       timeout=300)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout.strip().splitlines()[-1]), p.stderr


def test_with_an_empty_cache_nothing_compiles_and_the_opencv_path_serves_saying_how_to_compile(tmp_path):
    pytest.importorskip("numba", reason="the compiled kernels are the 'fast' extra (numba), not installed here")
    out, err = _first_reading({"XDG_CACHE_HOME": str(tmp_path), "TACTILE_FORCE_KERNELS": "auto"})
    assert out["seen"]["begun"] == 0  # no index in the cache: nothing is even tried
    assert out["compiled"] == 0 and not out["gate"] and not out["depth"]
    assert "tactile-force kernels" in err and "not compiled for this environment" in err
    assert not list(tmp_path.rglob("*.nbi"))  # and nothing was written for a later run either


def test_with_the_kernels_compiled_ahead_the_runtime_loads_them_and_compiles_nothing():
    compiled_kernels("gate", "depth")  # this process compiles them into the user's cache where missing
    out, err = _first_reading({"TACTILE_FORCE_KERNELS": "auto",
                               "XDG_CACHE_HOME": os.environ.get("XDG_CACHE_HOME", "")})
    assert out["seen"] == {"begun": 0, "finished": 0}, err  # every kernel from the cache
    assert out["compiled"] > 10 and out["gate"] and out["depth"] and out["path"].startswith("compiled kernels")


def test_the_robot_side_path_never_imports_numba_and_reads_the_same(tmp_path):
    off, _ = _first_reading({"TACTILE_FORCE_KERNELS": "off", "XDG_CACHE_HOME": str(tmp_path)})
    assert off["numba"] is False and off["seen"]["begun"] == 0 and "off" in off["path"]
    if compiled_path.installed():
        compiled_kernels("gate", "depth")
        on, _ = _first_reading({"TACTILE_FORCE_KERNELS": "auto",
                                "XDG_CACHE_HOME": os.environ.get("XDG_CACHE_HOME", "")})
        assert on["gate"] and on["depth"]
        assert on["readings"] == off["readings"]  # the same floats on both paths


def test_every_shipped_bundle_reads_the_same_on_both_paths(kernel_mode):
    """Whole runtimes over a virtual grasp, forces, flags and intervals compared exactly."""
    from tactile_force.edge import ContactGate, ForceRuntime, OnnxForceModel, RuntimeOptions, Sensor, VirtualDigitSource
    from tactile_force.edge.scene import shipped_bundles

    compiled_kernels("gate", "depth")

    def run(name: str, mode: str | None) -> list[tuple]:
        kernel_mode(mode)
        rt = ForceRuntime([Sensor("s", VirtualDigitSource(seed=2, n_grasps=1), ContactGate())],
                          OnnxForceModel(shipped_bundles()[name], threads=1), RuntimeOptions(deadline_ms=1e4))
        gate = rt.sensors[0].gate
        out = []
        while readings := rt.step():
            out += [(r.force_n, r.force_low_n, r.force_high_n, r.flags.names(), r.interval) for r in readings]
        kernels = gate._fw._k is not None if gate._fw is not None else None
        rt.close()
        return [kernels, out]

    for name in shipped_bundles():
        compiled, opencv = run(name, None), run(name, "off")
        assert compiled[0] is True and opencv[0] is False
        assert len(compiled[1]) > 30 and any(np.isfinite(r[0]) and r[0] > 1 for r in compiled[1])
        assert np.array_equal(np.array([r[:3] for r in compiled[1]]), np.array([r[:3] for r in opencv[1]]),
                              equal_nan=True), name
        assert [r[3:] for r in compiled[1]] == [r[3:] for r in opencv[1]], name


def test_a_bad_mode_is_refused_naming_the_variable(monkeypatch, kernel_mode):
    monkeypatch.setenv("TACTILE_FORCE_KERNELS", "fast")
    with pytest.raises(OptionsError, match="TACTILE_FORCE_KERNELS='fast'.*auto, off, compile"):
        compiled_path.kernel_mode()
    with pytest.raises(OptionsError, match="kernel mode 'sometimes'"):
        kernel_mode("sometimes")


def test_full_resolution_depth_without_scipy_names_the_paper_extra_before_any_frame(monkeypatch):
    import importlib.util

    from tactile_force.edge.depth import DepthOptions, DepthStage

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "scipy" else real(name, *a))
    with pytest.raises(MissingExtraError, match=r"tactile-force\[paper\]") as info:
        DepthStage(DepthOptions(mapping="edge/assets/virtual_digit_depth.npz"))
    assert info.value.extra == "paper"
    DepthStage(DepthOptions(mapping="edge/assets/virtual_digit_depth.npz", downscale=4))  # the compact grid: numpy


def test_the_kernels_verb_checks_and_compiles(tmp_path):
    pytest.importorskip("numba", reason="the compiled kernels are the 'fast' extra (numba), not installed here")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)
    cmd = [sys.executable, "-m", "tactile_force.edge.cli", "kernels", "--check"]
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=120)
    assert p.returncode == 1 and "not compiled for this environment" in p.stdout and "Traceback" not in p.stderr
