"""Malformed manifests beside a real graph: load_bundle either loads or raises a
TactileForceError with a message, never another exception type; `bundle verify` and
`bundle show` never print a traceback, and verify never says OK for a manifest that does
not fit its graph. (The bundle reader is the lead's; these tests pin its contract.)"""

from __future__ import annotations

import shutil

import pytest
from hypothesis import given

from benchmarks.robustness import default_bundle_dir, manifest_mutations, probe_manifest, targeted_manifests

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
