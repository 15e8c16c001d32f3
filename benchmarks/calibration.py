"""The calibration page (calibration.md): the default bundle before and after
``tactile-force calibrate-force`` on real DIGIT frames.

    python -m benchmarks.calibration      # writes docs/benchmarks/calibration.md (from a clone)

Fit: the 11 shared AUROVA frames (../shared/data/aurova_digit_grasp), leave-one-out on them.
Report only: the 11 held-out frames of the same grasp (aurova_digit_grasp_heldout), never
used for fitting or for choosing anything. Latency: batch-2 predict, one thread, with and
without the calibration applied.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from .harness.paths import cache_dir, require_repo, shared_data


def _p(model, rgb: np.ndarray) -> np.ndarray:
    return np.concatenate([model.predict(rgb[i:i + 2]) for i in range(0, len(rgb), 2)]).astype(np.float64)


def _lat(model, runs: int = 2000) -> tuple[float, float]:
    rgb = np.zeros((2, 320, 240, 3), np.uint8)
    t = np.empty(runs)
    for i in range(runs):
        t0 = time.perf_counter_ns()
        model.predict(rgb)
        t[i] = (time.perf_counter_ns() - t0) / 1e6
    return float(np.percentile(t, 50)), float(np.percentile(t, 99))


def study() -> tuple[list[list], dict]:
    from tactile_force.edge import default_bundle_path
    from tactile_force.edge.data.metrics import error_stats
    from tactile_force.edge.fitting.calibrate import calibrate_bundle, read_labelled
    from tactile_force.edge.model.onnx_model import OnnxForceModel

    rows: list[list] = []
    info: dict = {}
    fit, heldout = shared_data("aurova_digit_grasp"), shared_data("aurova_digit_grasp_heldout")
    for method in ("isotonic", "linear"):
        dest = cache_dir() / "calibrated_default" / method
        bundle, cal = calibrate_bundle(default_bundle_path(), fit, dest, method, overwrite=True)
        held = read_labelled(heldout)
        raw = OnnxForceModel(bundle, calibrate=False)
        calibrated = OnnxForceModel(bundle)
        before = error_stats(_p(raw, held.rgb), held.force)
        after = error_stats(_p(calibrated, held.rgb), held.force)
        b, a = cal.loo_before, cal.loo_after
        rows.append([method, f"{b.re_mean:.3f} +- {b.re_std:.3f}", f"{b.mae_mean:.2f} +- {b.mae_std:.2f}",
                     f"{a.re_mean:.3f} +- {a.re_std:.3f}", f"{a.mae_mean:.2f} +- {a.mae_std:.2f}",
                     f"{before.re_mean:.3f} +- {before.re_std:.3f}", f"{before.mae_mean:.2f} +- {before.mae_std:.2f}",
                     f"{after.re_mean:.3f} +- {after.re_std:.3f}", f"{after.mae_mean:.2f} +- {after.mae_std:.2f}"])
        if method == "isotonic":
            info["latency"] = {"raw": _lat(raw), "calibrated": _lat(calibrated)}
            info["knots"] = len(cal.raw_n)
            info["spearman"] = cal.spearman
    return rows, info


def main(argv: list[str] | None = None) -> int:
    from .harness.machine import describe_machine, header
    from .harness.stats import markdown_table

    out = require_repo("writing docs/benchmarks/calibration.md") / "docs" / "benchmarks" / "calibration.md"
    fit, heldout = shared_data("aurova_digit_grasp"), shared_data("aurova_digit_grasp_heldout")
    if not (fit / "images").is_dir() or not (heldout / "images").is_dir():
        print(f"needs {fit} and {heldout}", file=sys.stderr)
        return 2
    rows, info = study()
    (r50, r99), (c50, c99) = info["latency"]["raw"], info["latency"]["calibrated"]
    note = ("Default bundle (edge/models/default, trained on synthetic frames only). `calibrate-force` fitted on the "
            f"11 AUROVA frames ({fit.name}, 1.08-11.88 N, Spearman {info['spearman']:.3f}); leave-one-out (LOO) on "
            f"those 11; held-out: the 11 other frames of the same grasp ({heldout.name}, 1.50-11.93 N), report only. "
            "Both sets come from ONE grasp of ONE indenter on ONE sensor, interleaved in time: the held-out figures "
            "say the map generalises to other frames of that grasp, not to other objects or sensors.")
    text = header("Force calibration of the default bundle on real DIGIT frames",
                  "python -m benchmarks.calibration", describe_machine(), note)
    text += markdown_table(["method", "LOO RE before", "LOO MAE before (N)", "LOO RE after", "LOO MAE after (N)",
                            "held-out RE before", "held-out MAE before (N)", "held-out RE after",
                            "held-out MAE after (N)"], rows) + "\n\n"
    text += (f"Run-time cost (isotonic, {info['knots']} knots), batch-2 predict, one thread: p50 {r50:.3f} / "
             f"p99 {r99:.3f} ms raw, p50 {c50:.3f} / p99 {c99:.3f} ms calibrated (2000 calls each; the map itself is "
             "a bisect per value, under 1 us for two values).\n")
    out.write_text(text)
    print(text)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
