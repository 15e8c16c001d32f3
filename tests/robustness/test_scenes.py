"""Scenes with any key replaced, deleted or added: load_scene returns a Scene or raises a
SceneError/TactileForceError, never TypeError & co. (The scene reader is helper B1's;
tests/edge has its targeted validation tests.)"""

from __future__ import annotations

import pytest
from hypothesis import given

from benchmarks.robustness import Outcome, probe_scene, scene_mutations, targeted_scenes

from .conftest import ROBUST


@ROBUST
@given(scene_mutations())
def test_any_scene_loads_or_is_refused_clearly(tmp_path_factory, case):
    v = probe_scene(tmp_path_factory.mktemp("scene"), case)
    assert v.ok, v


@pytest.mark.parametrize("what, mutate, must_refuse", targeted_scenes(), ids=lambda x: x if isinstance(x, str) else "")
def test_issue_11_scenes(tmp_path, what, mutate, must_refuse):
    v = probe_scene(tmp_path, (what, mutate))
    assert v.ok, v
    if must_refuse:
        assert v.outcome is Outcome.CLEAR, v
