"""tactile_force.export: trained checkpoints -> verified (quantized) ONNX bundles. Needs torch."""
