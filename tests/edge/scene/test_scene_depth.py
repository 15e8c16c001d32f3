"""Depth options typed end to end: the scene's [depth] table (DepthSettings), the manifest's
DepthRecord and DepthOptions, merged by field name in one function (depth_options_for)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import pytest
from tactile_force.edge.bundle.manifest import DepthRecord
from tactile_force.edge.depth import DepthOptions
from tactile_force.edge.errors import SceneError
from tactile_force.edge.bundle.manifest import DepthRecord
from tactile_force.edge.runtime import ASSETS_DIR, depth_options_for
from tactile_force.edge.scene import DepthSettings, load_scene, parse_scene, scene_to_toml

SENSOR = {"sensor": [{"source": "virtual"}]}


def _manifest(**record) -> SimpleNamespace:
    return SimpleNamespace(depth=DepthRecord(**record))  # depth_options_for reads manifest.depth only


def test_the_scene_wins_then_the_manifest_then_the_default(tmp_path):
    manifest = _manifest(mapping="package:virtual_digit_depth.npz", mode="paper", paper_scale=9.0,
                         levels_per_px=3.0)
    opts = depth_options_for(DepthSettings(levels_per_px=5.0, gel_width_m=0.02), manifest)
    assert isinstance(opts, DepthOptions)
    assert opts.mapping == str(ASSETS_DIR / "virtual_digit_depth.npz")  # package:FILE resolved
    assert (opts.mode, opts.paper_scale) == ("paper", 9.0)  # from the manifest
    assert (opts.levels_per_px, opts.gel_width_m) == (5.0, 0.02)  # the scene overrides / adds
    assert opts.solver_dtype == DepthOptions("x").solver_dtype  # neither: the default
    own = depth_options_for(DepthSettings(mapping=tmp_path / "m.npz", mode="exact"), manifest)
    assert (own.mapping, own.mode) == (str(tmp_path / "m.npz"), "exact")


def test_any_field_named_like_a_depth_option_flows_through():
    """Generic over dataclasses.fields: a record field that DepthOptions also has needs no
    edit in the merge (here fields DepthRecord does not have); other fields are ignored."""

    @dataclasses.dataclass
    class FutureRecord:
        mapping: str = "calib.npz"
        solver_dtype: str = "float64"
        paper_dilation_px: int | None = 16
        not_an_option: str = "ignored"

    opts = depth_options_for(FutureRecord(), None)
    assert (opts.mapping, opts.solver_dtype, opts.paper_dilation_px) == ("calib.npz", "float64", 16)
    assert depth_options_for(DepthOptions("a.npz", mapping_step=2), None).mapping_step == 2  # options as settings


def test_the_manifest_depth_grid_becomes_the_stage_downscale():
    if "reduction" not in {f.name for f in dataclasses.fields(DepthRecord)}:
        pytest.skip("DepthRecord has no depth grid (reduction) in this tree")
    from tactile_force.edge.bundle.manifest import FrameReduction, Reduction

    opts = depth_options_for(None, _manifest(mapping="m.npz", reduction=FrameReduction(Reduction.AREA, 4)))
    assert (opts.downscale, opts.reduction) == (4, "area")
    assert depth_options_for(None, _manifest(mapping="m.npz")).downscale == 1  # full resolution


def test_missing_mapping_and_refused_values_name_the_key():
    with pytest.raises(SceneError, match=r"^depth\.mapping: missing; a depth bundle needs the colour->normal"):
        depth_options_for(DepthSettings(mode="paper"), None)
    with pytest.raises(SceneError, match=r"^depth: DepthOptions\.mode='fast': expected one of"):
        depth_options_for(None, _manifest(mapping="m.npz", mode="fast"))


@pytest.mark.parametrize("table, message", [
    ({"mapping_step": 3}, r"depth\.mapping_step: expected one of 1, 2, got 3$"),
    ({"saturated_fraction": 2}, r"depth\.saturated_fraction: expected a number in \[0, 1\], got 2$"),
    ({"mode": "fast"}, r"depth\.mode: expected one of 'exact', 'paper', got 'fast'$"),
    ({"levels_per_px": 0}, r"depth\.levels_per_px: expected a number > 0, got 0$"),
    ({"mapping": ""}, r"depth\.mapping: is empty; expected the colour->normal \.npz"),
    ({"levels": 2}, r"depth: unknown key 'levels'; allowed keys: mapping, mode, levels_per_px"),
])
def test_bad_depth_tables_name_the_file_and_key(tmp_path, table, message):
    with pytest.raises(SceneError, match=f"^{tmp_path / 's.toml'}: " + message):
        parse_scene({**SENSOR, "depth": table}, tmp_path / "s.toml")


def test_depth_table_paths_are_relative_to_the_scene_and_written_back(tmp_path):
    (tmp_path / "calib").mkdir()
    (tmp_path / "calib" / "m.npz").write_bytes(b"")
    scene = parse_scene({**SENSOR, "depth": {"mapping": "calib/m.npz", "mode": "paper", "mapping_step": 1}},
                        tmp_path / "s.toml")
    assert scene.depth == DepthSettings(mapping=tmp_path / "calib" / "m.npz", mode="paper", mapping_step=1)
    (tmp_path / "back.toml").write_text(scene_to_toml(scene))
    assert load_scene(tmp_path / "back.toml").depth == scene.depth
    assert parse_scene(SENSOR, tmp_path / "s.toml").depth == DepthSettings()  # nothing set
    assert Path(parse_scene({**SENSOR, "depth": {"mapping": "package:virtual_digit_depth.npz"}},
                            tmp_path / "s.toml").depth.mapping) == ASSETS_DIR / "virtual_digit_depth.npz"


def test_depth_mapping_from_flags_is_read_like_a_scene_key(tmp_path, monkeypatch):
    from tactile_force.edge.scene import scene_from_flags

    monkeypatch.chdir(tmp_path)
    scene = scene_from_flags("virtual", depth_mapping="calib/m.npz")
    assert scene.depth == DepthSettings(mapping=tmp_path / "calib" / "m.npz")  # relative to the working directory
    with pytest.raises(SceneError, match=r"^command line: depth\.mapping: is empty; expected the colour->normal"):
        scene_from_flags("virtual", depth_mapping="")


@pytest.mark.parametrize("key, value, message", [
    ("mode", "fast", r"depth\.mode: expected one of 'exact', 'paper', got 'fast'$"),
    ("levels_per_px", -1, r"depth\.levels_per_px: expected a number > 0, got -1$"),
    ("paper_scale", 0, r"depth\.paper_scale: expected a number > 0, got 0$"),
])
def test_the_manifest_depth_record_is_checked_when_read(key, value, message):
    """The manifest's depth record is read by the same typed reader, so a bundle with a bad
    depth option is refused at load, naming the key, not when the stage is built."""
    import copy
    import json

    from tactile_force.edge.bundle.manifest import manifest_from_json
    from tactile_force.edge.errors import BundleError
    from tactile_force.edge.scene import shipped_bundles

    if "d" not in shipped_bundles():
        pytest.skip("no shipped depth bundle in this install")
    raw = json.loads((shipped_bundles()["d"] / "model.json").read_text())
    manifest_from_json(copy.deepcopy(raw), "model.json")  # as shipped: fine
    raw["depth"][key] = value
    with pytest.raises(BundleError, match="^model.json: " + message):
        manifest_from_json(raw, "model.json")
