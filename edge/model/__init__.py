"""The force model: ONNX Runtime inference on a verified bundle (``onnx_model``)."""

from __future__ import annotations

from .onnx_model import OnnxForceModel

__all__ = ["OnnxForceModel"]
