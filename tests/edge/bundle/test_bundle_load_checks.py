"""Every loader refuses a bundle ``bundle verify`` refuses: one check at load
(:func:`tactile_force.edge.bundle.store.check_bundle_files` in ``load_bundle``), so ``run``,
``OnnxForceModel``, ``calibrate-force``, ``bench``, the OAK backend and the export verbs' inputs
answer as ``verify`` does; and the manifest's records are checked for their own consistency
(ranges ordered, a plain name, no depth record on an RGBmod bundle) at every load."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from tactile_force.edge.bundle import graph_facts as gf
from tactile_force.edge.bundle.store import load_bundle, write_bundle
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.errors import BundleError
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.scene import default_bundle_path


def _edited(dest: Path, edit) -> Path:
    """A copy of the shipped default bundle whose model.json is changed by ``edit(dict)`` (the
    ONNX file and its recorded sha256 unchanged: only the manifest's claims differ)."""
    shutil.copytree(default_bundle_path(), dest)
    raw = json.loads((dest / "model.json").read_text())
    edit(raw)
    (dest / "model.json").write_text(json.dumps(raw, indent=2))
    return dest


def _linked(dest: Path, name: str) -> Path:
    """A copy of the default bundle whose ``name`` is a symbolic link to a copy outside it."""
    shutil.copytree(default_bundle_path(), dest)
    outside = dest.parent / f"outside-{name}"
    shutil.move(dest / name, outside)
    os.symlink(outside, dest / name)
    return dest


def _swap_colour_ranges(m: dict) -> None:
    d = m["data_stats"]
    d["cell_lo"], d["cell_hi"] = d["cell_hi"], d["cell_lo"]


def _depth_on_rgbmod(m: dict) -> None:
    m["depth"] = {"mapping": "package:virtual_digit_depth.npz"}


#: (case, how the bundle is made, words the refusal must hold: the failing field or file)
CASES = [
    ("int8-dynamic claim", lambda d: _edited(d, lambda m: m.update(precision="int8-dynamic")),
     ["precision", "int8-dynamic", "fp32"]),
    ("input_scale 0.5", lambda d: _edited(d, lambda m: m["architecture"].update(input_scale=0.5)),
     ["architecture.input_scale 0.5", "80 x 60"]),
    ("model.onnx linked from outside", lambda d: _linked(d, "model.onnx"), ["model.onnx ->", "outside the bundle"]),
    ("model.json linked from outside", lambda d: _linked(d, "model.json"), ["model.json ->", "outside the bundle"]),
    ("data_stats colour ranges swapped", lambda d: _edited(d, _swap_colour_ranges),
     ["data_stats", "cell_lo[0]", "cell_hi[0]", "low <= high"]),
    ("name with a path separator", lambda d: _edited(d, lambda m: m.update(name="../evil")),
     ["name '../evil'", "'/'", "plain name"]),
    ("name with a newline", lambda d: _edited(d, lambda m: m.update(name="ok\nforce 0.0 N")),
     ["name", "'\\n'", "plain name"]),
    ("depth record on RGBmod", lambda d: _edited(d, _depth_on_rgbmod),
     ["depth", "'rgbmod'", "reads no depth image"]),
]
IDS = [c[0] for c in CASES]


@pytest.fixture(params=CASES, ids=IDS)
def refused(request, tmp_path):
    _, make, words = request.param
    return make(tmp_path / "b"), words


def _names(msg: str, path: Path, words: list[str]) -> None:
    assert str(path) in msg and "Traceback" not in msg, msg
    for w in words:
        assert w in msg, (w, msg)


def test_verify_load_bundle_and_the_model_refuse_it_naming_the_bundle_and_the_field(refused, capsys):
    path, words = refused
    rc = cli_main(["bundle", "verify", str(path)])
    err = capsys.readouterr().err
    assert rc == 1 and "FAILED" in err
    _names(err, path, words)
    for load in (load_bundle, OnnxForceModel):
        with pytest.raises(BundleError) as exc:
            load(path)
        _names(str(exc.value), path, words)


def test_run_refuses_it_before_any_frame(refused, tmp_path):
    path, words = refused
    out = tmp_path / "readings.csv"
    proc = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "run", "--source", "virtual", "--bundle",
                           str(path), "--max-frames", "3", "--out", str(out)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2, proc.stderr
    _names(proc.stderr, path, words)
    assert not out.exists()


def test_calibrate_force_and_the_oak_backend_refuse_it(refused, tmp_path, capsys):
    from tactile_force.edge.fitting.calibrate import calibrate_bundle

    path, words = refused
    with pytest.raises(BundleError) as exc:
        calibrate_bundle(path, tmp_path / "presses", tmp_path / "cal")
    _names(str(exc.value), path, words)
    from tactile_force.firmware_bridge.oak import OakForceModel, OakOptions

    with pytest.raises(BundleError) as exc:
        OakForceModel(path, OakOptions(archive=tmp_path / "model.tar.xz"))
    _names(str(exc.value), path, words)


def test_write_bundle_refuses_what_load_would_refuse(tmp_path):
    b = load_bundle(default_bundle_path())
    data = b.onnx_path.read_bytes()
    for field, value, words in (("name", "a/b", "plain name"), ("name", "x\ny", "plain name"),
                                ("precision", "int8-dynamic", "precision: the manifest says int8-dynamic")):
        m = load_bundle(default_bundle_path()).manifest
        setattr(m, field, type(getattr(m, field))(value))
        dest = tmp_path / f"w-{field}"
        with pytest.raises(BundleError, match=words):
            write_bundle(dest, data, m)
        assert not dest.exists() and not list(tmp_path.glob(f".{dest.name}.*"))
    m = b.manifest
    assert m.data_stats is not None
    m.data_stats.cell_lo, m.data_stats.cell_hi = m.data_stats.cell_hi, m.data_stats.cell_lo
    with pytest.raises(BundleError, match=r"data_stats: cell_lo\[0\]"):
        write_bundle(tmp_path / "w-stats", data, m)


def test_the_graph_is_read_once_per_sha256(tmp_path, monkeypatch):
    """The facts depend on the graph's bytes only: a second load of the same graph (another
    runtime, a scene's preflight then its build, a copy of the bundle) does not parse it again;
    another graph is parsed."""
    calls = []
    real = gf.facts_of_bytes
    monkeypatch.setattr(gf, "_FACTS_BY_SHA256", {})
    monkeypatch.setattr(gf, "facts_of_bytes", lambda data, where: calls.append(where) or real(data, where))
    shutil.copytree(default_bundle_path(), tmp_path / "copy")
    load_bundle(default_bundle_path())
    load_bundle(tmp_path / "copy")
    OnnxForceModel(default_bundle_path(), warmup=0).close()
    assert len(calls) == 1
    from tactile_force.edge.scene import shipped_bundles

    load_bundle(shipped_bundles()["d"])
    assert len(calls) == 2


def test_the_shipped_bundles_pass_every_load_check():
    from tactile_force.edge.scene import shipped_bundles

    for path in shipped_bundles().values():
        b = load_bundle(path)
        assert b.manifest.name and "/" not in b.manifest.name
        rc = cli_main(["bundle", "verify", str(path)])
        assert rc == 0, path
