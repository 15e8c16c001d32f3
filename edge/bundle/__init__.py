"""The model bundle and its records: ``model.onnx`` + ``model.json``.

``store`` reads and writes bundles (sha256, confinement, crash-safe replacement);
``manifest`` is the one typed, versioned manifest, whose sections are the records beside it:
``data_stats`` (what the training frames looked like), ``interval`` (every reading's error
bar), ``force_calibration`` (the per-sensor force map and the sensor's fingerprint);
``graph_facts`` reads what the ONNX graph really holds.
"""

from __future__ import annotations

from .store import Bundle, load_bundle, read_manifest, sha256_file, stale_partials, write_bundle

__all__ = ["Bundle", "load_bundle", "read_manifest", "sha256_file", "stale_partials", "write_bundle"]
