"""Fixtures for export tests: real frames, a module-scoped temp folder."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("torch", reason="export tests need the 'export' extra (torch)")
pytest.importorskip("onnx", reason="export tests need the 'export' extra (onnx)")

from tests.conftest import shared_data  # noqa: E402


@pytest.fixture(scope="module")
def aurova() -> Path:
    """The 11 real DIGIT frames with depth images and forces (authors' layout)."""
    return shared_data("aurova_digit_grasp")


@pytest.fixture(scope="module")
def module_tmp(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("export")
