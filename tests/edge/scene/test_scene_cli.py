"""Scenes (TOML), the run / scene show / demo CLI, and what a CPU RGBmod scene imports."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import pytest
from tactile_force.edge import SceneError
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.cli.demo import run_demo
from tactile_force.edge.cli.replay_report import PLOT_NAME, _plot_cv
from tactile_force.edge.data.dataset import AuthorsDataset, AuthorsDatasetWriter
from tactile_force.edge.scene import build_scene, default_bundle_path, describe_scene, load_scene
from tactile_force.edge.sources import ReplayFolderSource

from tests.conftest import shared_data

from tests.conftest import REPO  # noqa: E402


def _scene(tmp_path: Path, bundle: Path, aurova: Path, extra: str = "", name: str = "scene.toml") -> Path:
    bg = shared_data("digit_backgrounds", "aurova_background_b.png")
    text = textwrap.dedent(f"""
        [runtime]
        bundle = "{bundle}"
        deadline_ms = 1000.0

        [[sensor]]
        name = "left"
        source = "replay"
        path = "{aurova}"
        background = "{bg}"

        [[output]]
        kind = "csv"
        path = "{tmp_path}/out/readings.csv"

        [[output]]
        kind = "jsonl"
        path = "{tmp_path}/out/readings.jsonl"
        """) + extra
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("snippet, match", [
    ('[runtime]\nbackend = "gpu"\n', r"runtime\.backend: expected one of 'cpu', 'oak', got 'gpu'"),
    ('[runtime]\ndeadline = 5\n', r"runtime: unknown key 'deadline'; allowed keys: bundle, backend, "),
    ('[runtime]\nthreads = "two"\n[[sensor]]\nsource = "camera"\n',
     r"runtime\.threads: expected an integer >= 1, got 'two'"),
    ('[[sensor]]\nsource = "usb"\n', r"sensor\[0\]\.source: expected one of 'camera', .*got 'usb'"),
    ('[[sensor]]\nsource = "replay"\n', r"sensor\[0\]\.path: missing; expected a replay folder"),
    ('[[sensor]]\nsource = "camera"\ngate = { blur = 4 }\n',
     r"sensor\[0\]\.gate: GateOptions\.blur=4: expected an odd integer"),
    ('[[sensor]]\nsource = "camera"\n[[output]]\nkind = "csv"\n', r"output\[0\]: output 'csv' needs 'path'"),
    ('[runtime\n', r"not valid TOML"),
    ('', r"no \[\[sensor\]\] tables"),
])
def test_scene_errors_name_key_and_expected_value(tmp_path, snippet, match):
    p = tmp_path / "bad.toml"
    p.write_text(snippet)
    with pytest.raises(SceneError, match=match):
        load_scene(p)


def test_scene_show_lists_only_needed_stages(tmp_path, rgb_bundle, make_bundle, aurova_dir):
    p = _scene(tmp_path, rgb_bundle, aurova_dir)
    out = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "scene", "show", str(p)],
                         capture_output=True, text=True, cwd=REPO, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "source:left" in out.stdout and "gate:left" in out.stdout and "inference    cpu" in out.stdout
    assert "depth:" not in out.stdout and "no depth stage" in out.stdout
    d = _scene(tmp_path, make_bundle("scene_d", variant="dmod"), aurova_dir, name="d.toml")
    lines = describe_scene(load_scene(d))
    assert any(line.strip().startswith("depth:left") for line in lines)


def test_cpu_rgbmod_scene_imports_no_torch_or_device_libraries(tmp_path, rgb_bundle, aurova_dir):
    p = _scene(tmp_path, rgb_bundle, aurova_dir)
    code = textwrap.dedent(f"""
        import json, sys
        from tactile_force.edge.cli import main
        from tactile_force.edge.scene import build_scene, load_scene
        built = build_scene(load_scene({str(p)!r}))
        depth_built = [s.depth is not None for s in built.runtime.sensors]
        stages = built.runtime.stages
        built.close()
        rc = main(["run", "--scene", {str(p)!r}, "--force"])  # build_scene above wrote the CSV
        heavy = [m for m in ("torch", "depthai", "usb", "hid", "onnx", "matplotlib") if m in sys.modules]
        print(json.dumps({{"rc": rc, "heavy": heavy, "depth_built": depth_built, "stages": stages}}))
        """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=120)
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["rc"] == 0
    assert res["heavy"] == []
    assert res["depth_built"] == [False]
    assert not any(s.startswith("depth") for s in res["stages"])
    rows = (tmp_path / "out" / "readings.jsonl").read_text().splitlines()
    assert len(rows) == 11  # the replay of the real AUROVA grasp: one reading per frame
    recs = [json.loads(r) for r in rows]
    assert all(r["flags"] in ("", "late") and r["truth_n"] > 1.0 for r in recs)
    assert len((tmp_path / "out" / "readings.csv").read_text().splitlines()) == 12


def test_run_cli_in_process(tmp_path, rgb_bundle, aurova_dir, capsys):
    p = _scene(tmp_path, rgb_bundle, aurova_dir, extra='\n[[output]]\nkind = "stdout"\n')
    assert cli_main(["run", "--scene", str(p), "--max-frames", "4"]) == 0
    out = capsys.readouterr()
    assert len([line for line in out.out.splitlines() if line.strip().startswith("left #")]) == 4
    assert "latency ms (p50 / p99)" in out.err


def test_oak_scene_without_oak_falls_back_or_fails_clearly(tmp_path, rgb_bundle, aurova_dir):
    p = _scene(tmp_path, rgb_bundle, aurova_dir, name="oak.toml")
    archive = tmp_path / "missing.tar.xz"
    text = p.read_text().replace(
        "deadline_ms = 1000.0", f'deadline_ms = 1000.0\nbackend = "oak"\nfallback = "cpu"\noak_archive = "{archive}"')
    p.write_text(text)
    built = build_scene(load_scene(p))
    try:
        if built.runtime.backend == "cpu":
            assert any("falling back to the CPU" in n for n in built.notes)
    finally:
        built.close()
    p.write_text(text.replace('fallback = "cpu"\n', ""))
    try:
        built = build_scene(load_scene(p))
        built.close()  # an OAK is attached on this machine
    except SceneError as exc:
        assert "fallback" in str(exc)


def test_example_scenes_parse_and_write_outside_the_package(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_FORCE_SHARED_DATA", str(shared_data()))
    monkeypatch.chdir(tmp_path)
    for p in sorted((REPO / "edge" / "scenes").glob("*.toml")):
        scene = load_scene(p)  # paths checked too: the replay scene's inputs exist, outputs are writable
        lines = describe_scene(scene)
        assert any("inference" in line for line in lines), p
        assert scene.bundles == [default_bundle_path()]
        for o in scene.outputs:  # relative output paths land in the working directory
            assert o.path is None or o.path.parent == tmp_path, (p, o.path)


def _grasp_dataset(tmp_path: Path, aurova_dir: Path) -> Path:
    """Real frames in the authors' layout: 6 no-contact frames (0 N), then the real grasp."""
    root = tmp_path / "grasp"
    bg = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")))
    ds = AuthorsDataset(aurova_dir)
    with AuthorsDatasetWriter(root) as w:
        for _ in range(6):
            w.write(bg, 0.0)
        for s in ds:
            w.write(s.frame, s.force_n)
    return root


def test_demo_path_writes_plot_summary_and_readings(tmp_path, rgb_bundle, aurova_dir):
    src = ReplayFolderSource(_grasp_dataset(tmp_path, aurova_dir))
    s = run_demo(src, rgb_bundle, tmp_path / "demo", echo=None)
    summary = json.loads(Path(s.summary_json).read_text())
    assert summary["readings"] == 17 and summary["contact_readings"] == 11
    assert summary["error"]["n"] == 11 and summary["error"]["mae_mean"] > 0
    assert summary["gate_agreement"] == 1.0  # 6 frames learnt as background, then contact on all 11
    assert set(summary["latency_ms"]) == {"source", "gate", "depth", "inference", "total"}
    img = cv2.imread(s.plot)
    assert img is not None and img.shape[0] > 100
    assert len(Path(s.readings_csv).read_text().splitlines()) == 18


def test_plot_without_matplotlib_uses_opencv(tmp_path):
    import numpy as np

    path = tmp_path / "p.png"
    t = np.linspace(0, 2, 50)
    assert _plot_cv(t, np.sin(t) + 2, np.sin(t) + 2.1, path) == "opencv"
    assert cv2.imread(str(path)).shape == (360, 900, 3)


def test_demo_cli_with_virtual_digit_and_default_bundle(tmp_path, capsys):
    pytest.importorskip("tactile_force.edge.synthetic", reason="virtual DIGIT not installed")
    from tactile_force.edge import synthetic

    if not hasattr(synthetic, "VirtualDigitSource"):
        pytest.skip("VirtualDigitSource not written yet")
    if not (default_bundle_path() / "model.json").is_file():
        pytest.skip(f"default bundle not shipped yet at {default_bundle_path()}")
    assert cli_main(["demo", "--out", str(tmp_path / "d"), "--grasps", "1"]) == 0
    assert (tmp_path / "d" / "summary.json").is_file() and (tmp_path / "d" / PLOT_NAME).is_file()
    from tactile_force.edge.report.host import cpu_line

    assert cpu_line() in capsys.readouterr().out.splitlines()  # the host its latency was measured on
