"""Malformed manifests beside a real graph: load_bundle either loads or raises a
TactileForceError with a message, never another exception type; `bundle verify` and
`bundle show` never print a traceback, and verify never says OK for a manifest that does
not fit its graph. (The bundle reader is the lead's; these tests pin its contract.)"""

from __future__ import annotations

import shutil

import pytest
from hypothesis import given

from benchmarks.robustness import default_bundle_dir, manifest_mutations, probe_manifest, targeted_manifests
from benchmarks.robustness_bundles import BUNDLES

from .conftest import ROBUST


@pytest.fixture(scope="module")
def bundle_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bundle")
    shutil.copy(default_bundle_dir() / "model.onnx", folder / "model.onnx")
    return folder


@ROBUST
@given(manifest_mutations())
def test_any_manifest_loads_or_is_refused_clearly(bundle_folder, case):
    v = probe_manifest(bundle_folder, case)
    assert v.ok, v


@pytest.mark.parametrize("case", targeted_manifests(), ids=lambda c: c[0][:50])
def test_issue_11_manifests_through_load_verify_and_show(bundle_folder, case):
    v = probe_manifest(bundle_folder, case, cli=True)
    assert v.ok, v


@pytest.mark.parametrize("i", range(len(BUNDLES)), ids=[c[0] for c in BUNDLES])
def test_bundles_verify_refuses_are_refused_by_every_loader(tmp_path, i):
    """The suite's category: load_bundle, run and bundle verify each refuse it, naming the
    bundle and the field (on commit 53726eb run and load_bundle accepted every one, and verify
    passed the records that contradict themselves)."""
    from benchmarks.robustness_bundles import Outcome, bundle_cases

    what, probe = bundle_cases(tmp_path)[i]
    v = probe()
    assert v.outcome is Outcome.CLEAR, (what, v)


def test_scene_paths_are_named_for_what_they_are(tmp_path):
    from benchmarks.robustness_bundles import Outcome, scene_path_cases

    for what, probe in scene_path_cases(tmp_path):
        v = probe()
        assert v.outcome is Outcome.CLEAR, (what, v)
