"""Paper depth mode: when the gate re-learns its background after a background_mismatch, the
depth stage's zero-depth reference follows. Real AUROVA frames and background, the
real gate, depth stage (the shared paper MLP) and ONNX Runtime model, run from a scene file."""

from __future__ import annotations

import textwrap

import cv2
import numpy as np
from tactile_force.edge.reading import Flags
from tactile_force.edge.runtime import build_depth_stage
from tactile_force.edge.scene import build_scene, load_scene

from tests.conftest import shared_data


def test_relearnt_background_resets_the_paper_depth_reference(tmp_path, make_bundle, aurova_dir):
    from tactile_force.edge.data.dataset import AuthorsDatasetWriter

    bg_path = shared_data("digit_backgrounds", "aurova_background_b.png")
    bg = cv2.imread(str(bg_path))
    dim = np.clip(bg * 0.8, 0, 255).astype(np.uint8)  # an LED step: the given background no longer fits
    press = np.clip(cv2.imread(str(aurova_dir / "images" / "1510.png")) * 0.8, 0, 255).astype(np.uint8)
    root = tmp_path / "grasp"
    with AuthorsDatasetWriter(root) as w:
        for _ in range(14):
            w.write(dim, 0.0)
        for _ in range(3):
            w.write(press, 5.0)
    scene_file = tmp_path / "paper.toml"
    scene_file.write_text(textwrap.dedent(f"""
        [runtime]
        bundle = "{make_bundle('paper_rgbd', variant='rgbmod+d')}"
        deadline_ms = 1000.0
        [gate]
        relearn_frames = 10
        [depth]
        mode = "paper"
        mapping = "{shared_data('aurova_digit_depth_mlp.npz')}"
        [[sensor]]
        name = "left"
        source = "replay"
        path = "{root}"
        background = "{bg_path}"
        """))
    scene = load_scene(scene_file)
    built = build_scene(scene)
    stage = built.runtime.sensors[0].depth
    first = stage.reference.copy()  # from the given background image
    readings: list = []
    try:
        built.runtime.run([], on_reading=readings.append)
    finally:
        built.close()
    gate = built.runtime.sensors[0].gate
    assert gate.relearned == 1
    flags = [r.flags for r in readings]
    assert all(f & Flags.BACKGROUND_MISMATCH for f in flags[:10])

    def reference_of(frame: np.ndarray) -> np.ndarray:
        fresh = build_depth_stage(scene.depth, built.runtime.model.bundle.manifest)
        fresh.set_reference([frame])
        return fresh.reference

    assert np.allclose(first, reference_of(bg))
    assert not np.allclose(stage.reference, first)  # re-set ...
    assert np.allclose(stage.reference, reference_of(dim))  # ... from the frame the gate re-learnt
    served = readings[14:]
    assert all(not (r.flags & (Flags.INVALID_INPUT | Flags.BACKGROUND_MISMATCH)) and np.isfinite(r.force_n)
               for r in served), [(r.flags.names(), r.detail) for r in served]
    assert all(not (r.flags & Flags.NO_CONTACT) for r in served)  # the presses reach the CNN with depth
