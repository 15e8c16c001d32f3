"""docs/benchmarks/README.md: links every table and plot the benchmarks wrote."""

from __future__ import annotations

from pathlib import Path

PAGES = (
    ("check.md", "The under-1 ms check through ForceRuntime: total p50 / p90 / p99 of the best RGBmod, the "
                 "runtime's overhead over a bare onnxruntime session, D and RGBmod+D beside it, ratio to PyTorch "
                 "eager, the machine's load per attempt"),
    ("latency.md", "Issue 12's goals (before / after); latency per stage through ForceRuntime (gate, depth, "
                   "inference, total, glue, bare onnxruntime, overhead) for every variant, precision, size and "
                   "thread count; PyTorch eager, onnxruntime and OpenVINO side by side; two sensors; the demo's "
                   "late readings; masked depth evaluation; the gate's cost"),
    ("one_downscale.md", "Issue 18's goals (one downscale per frame): runtime total and gate against a bare "
                         "onnxruntime session on the previous default graph (c1733e6), interleaved in one run; "
                         "how the frame is reduced; the graph node by node and its variants; the under-1 ms check "
                         "10 times back to back (`python -m benchmarks one-downscale --out docs/benchmarks`)"),
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
             "", "    python -m benchmarks all --check --out docs/benchmarks   # everything, into these docs",
             "    python -m benchmarks latency --check --out docs/benchmarks   # only latency.md and check.md",
             "    python -m benchmarks all --quick   # smoke run into out/benchmarks (never into the docs)", "",
             "Without `--out` results go to out/benchmarks (git-ignored). The check records the machine's load and",
             "repeats when it is busy: 'machine busy' is reported apart from 'over budget'.", "",
             "Trained models come from `python -m benchmarks.reference` (synthetic frames, CPU);",
             "configs it has not trained yet are listed as 'not trained'.", ""]
    for name, what in PAGES:
        mark = "" if (out / name).exists() else " (not generated yet)"
        lines.append(f"- [{name}]({name}): {what}{mark}")
    known = {name for name, _ in PAGES} | {"README.md"}
    for f in sorted(out.glob("*.md")) if out.is_dir() else []:  # pages other studies wrote here
        if f.name not in known:
            title = next((ln.lstrip("# ").strip() for ln in f.read_text().splitlines() if ln.startswith("#")), "")
            lines.append(f"- [{f.name}]({f.name}): {title}")
    p = out / "README.md"
    p.write_text("\n".join(lines) + "\n")
    return p
