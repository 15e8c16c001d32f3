"""The force model: ONNX Runtime inference on a verified bundle (``onnx_model``), and the
bundle ladder that picks a bundle by its latency on this host (``ladder``)."""

from __future__ import annotations

from .onnx_model import OnnxForceModel

__all__ = ["OnnxForceModel"]
