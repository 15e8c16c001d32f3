"""docs/benchmarks/README.md: links every table and plot the benchmarks wrote."""

from __future__ import annotations

from pathlib import Path

PAGES = (
    ("check.md", "The under-1 ms check: gate + inference p50 / p90 / p99 of the best RGBmod, D and RGBmod+D beside it, "
                 "ratio to PyTorch eager"),
    ("latency.md", "Latency per stage (decode, gate, depth, inference, total), every variant, precision, size "
                   "and thread count, GMACs, the paper's way (PyTorch eager) beside ours, the gate's cost"),
    ("error_vs_runtime.md", "Error (RE / MAE, per 1 N bin; synthetic held-out indenters and real AUROVA frames) "
                            "against p50 / p99 of every trained bundle"),
    ("error_vs_runtime.png", "Pareto plot: RE against p99 latency"),
    ("quantization.md", "Quantization study: calibration method x per-channel/per-tensor x nodes kept float; "
                        "evaluating at a smaller input scale than trained"),
    ("stability.md", "Stiff and extreme cases: non-finite outputs, flags, monotone sweeps, int8 vs fp32"),
)


def write_readme(out: Path) -> Path:
    lines = ["# Benchmarks", "",
             "Every page states the machine and the command that made it. Regenerate everything with",
             "", "    python -m benchmarks all          # ~15 min on a 2-core CPU; --quick for a smoke run",
             "    python -m benchmarks --check      # the under-1 ms check (exit 1 when it fails)", "",
             "Trained models come from `python -m benchmarks.reference` (synthetic frames, CPU);",
             "configs it has not trained yet are listed as 'not trained'.", ""]
    for name, what in PAGES:
        mark = "" if (out / name).exists() else " (not generated yet)"
        lines.append(f"- [{name}]({name}): {what}{mark}")
    p = out / "README.md"
    p.write_text("\n".join(lines) + "\n")
    return p
