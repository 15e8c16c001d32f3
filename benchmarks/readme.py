"""The index of the benchmark pages (README.md in the pages' folder): one line per page, with
the command that makes it; pages whose code was retired say so."""

from __future__ import annotations

from pathlib import Path

#: (page, what it holds, the command that makes it; "" for pages whose code was retired)
PAGES = (
    ("bench/report.md", "`tactile-force bench`, the installed robot-side verb (no torch): the four shipped "
                        "bundles (the default fp32 RGBmod, the int8 RGBmod, D, RGBmod+D) through ForceRuntime on "
                        "this host with the under-1 ms verdict per bundle and each graph alone at the cadence "
                        "(+ report.json, pareto.png)",
     "tactile-force bench --out docs/benchmarks/bench"),
    ("cadence.md", "Latency at the sensor's cadence (60 fps): one sensor and eight phase-shifted against a bare "
                   "session at the same cadence, warm-ups off / on, the floor under the runtime (each frame's one "
                   "downscale then the bare call) against the ms it may add, where the cold time goes per stage, "
                   "which parts "
                   "of the warm-up pay, the bench verdict of the default and the int8 RGBmod over several runs (+ "
                   "cadence.json)",
     "python -m benchmarks cadence --out docs/benchmarks"),
    ("instructions.md", "Work per reading in instructions (valgrind's callgrind, load-independent): each shipped "
                        "bundle's ForceRuntime reading against its bare graph's call, per stage (gate, depth, glue "
                        "+ judge) and per library (onnxruntime, OpenCV, numpy, OpenBLAS, libc, the interpreter), "
                        "on the compiled kernels and on the robot-side install's OpenCV path, before / after, and "
                        "what each goal leaves for the checks beside the one downscale (+ instructions.json)",
     "python -m benchmarks instructions --out docs/benchmarks"),
    ("footprint.md", "What one reading touches: the distinct cache lines of code and data of a ForceRuntime reading "
                     "and of its bare graph call, per stage and shipped bundle (callgrind's cache simulator, "
                     "load-independent; the cold cost at the sensor's cadence) (+ footprint.json)",
     "python -m benchmarks footprint --out docs/benchmarks"),
    ("default_bundle.md", "Which shipped bundle ships as the default: tactile-force bench run several times on one "
                          "host, each bundle's p99 at 60 fps against its error, the Pareto front per run and the "
                          "choice (+ default_bundle.json)",
     "python -m benchmarks default-bundle --bench-runs 5 --out docs/benchmarks"),
    ("startup.md", "Start-up: process start to the first reading, per install (robot-side, with the fast extra), "
                   "with an empty and a warm cache, beside the import floor; the kernels' compile time; the demo's "
                   "first and second run (+ startup.json)",
     "python -m benchmarks startup --python ROBOT_VENV/bin/python --python DEV_VENV/bin/python --out docs/benchmarks"),
    ("depth_bundles.md", "The shipped compact D and RGBmod+D bundles: error on the synthetic test split through "
                         "ForceRuntime, and their total p50 against RGBmod interleaved",
     "python -m benchmarks.depth_bundles --write docs/benchmarks/depth_bundles.md"),
    ("intervals.md", "Every reading's error bar: coverage and width per force bin, synthetic and real after "
                     "calibrate-force, cost per reading", "python -m benchmarks intervals --out docs/benchmarks"),
    ("trust.md", "Frames that cannot be judged: silent wrong readings, false alarms, the trust checks' cost",
     "python -m benchmarks trust --out docs/benchmarks"),
    ("calibration.md", "Force calibration of the default bundle on real DIGIT frames",
     "python -m benchmarks.calibration"),
    ("quantization.md", "Quantization study: calibration method x per-channel/per-tensor x nodes kept float; "
                        "evaluating at a smaller input scale than trained",
     "python -m benchmarks quant --out docs/benchmarks"),
    ("latency.md", "Latency per stage through ForceRuntime for every variant, precision, size and thread count; "
                   "PyTorch eager, onnxruntime and OpenVINO side by side; two sensors; the demo's late readings; "
                   "masked depth evaluation; the gate's cost",
     ""),
    ("error_vs_runtime.md", "Error (RE / MAE; synthetic held-out test indenters and real AUROVA frames) against "
                            "total p50 / p99 back to back and at 60 fps of every shipped bundle "
                            "(+ error_vs_runtime.png, the Pareto plot, and error_vs_runtime.json)",
     "python -m benchmarks error --out docs/benchmarks"),
    ("stability.md", "Stiff and extreme cases: non-finite outputs, flags, monotone sweeps, int8 vs fp32; every "
                     "shipped bundle (edge/models) beside trained and random-weight ones (`--shipped-only`: the "
                     "shipped ones alone, no torch)",
     "python -m benchmarks stability --out docs/benchmarks"),
    ("one_downscale.md", "One downscale per frame: runtime total and gate against a bare onnxruntime session on "
                         "the previous default graph, the graph node by node, the under-1 ms check 10 times", ""),
    ("floors.md", "The least a gate and a runtime cost on this host against a bare session on the previous "
                  "default graph", ""),
    ("dst_halves.md", "The depth stage's DST-I by its even and odd halves against the dense products: instructions "
                      "per reading and how far the depth bundles' readings move", ""),
    ("int8_head.md", "int8: keeping the head's input in float", ""),
    ("distillation.md", "Distillation: students vs teacher vs labels", ""),
    ("distillation_small_student.md", "Distillation: a smaller student, more frames and epochs", ""),
)


def write_readme(out: Path) -> Path:
    """Write ``out``/README.md: every page of :data:`PAGES` (marked when not in ``out``), then
    any other page found there."""
    lines = ["# Benchmarks", "",
             "Every page states the command that made it, the commit of the code that measured it, the machine "
             "and its load. `python -m benchmarks --help` lists the commands; results go to out/benchmarks "
             "(git-ignored) unless `--out` names this folder, and `--quick` runs never come here. Trained models "
             "come from `python -m benchmarks.reference` (synthetic frames, CPU); configs it has not trained yet "
             "are listed as 'not trained'. The under-1 ms verdict on a host is `tactile-force bench` "
             "([bench/report.md](bench/report.md)); the old check.md (measured at commit 940127e on a retired "
             "design) went with its code at commit 3e8ae14.", ""]
    for name, what, command in PAGES:
        mark = "" if (out / name).exists() else " (not generated yet)"
        how = f" (`{command}`)" if command else " (its code was retired: the page names the commit to check out)"
        lines.append(f"- [{name}]({name}): {what}{how}{mark}")
    known = {name for name, _, _ in PAGES} | {"README.md"}
    for f in sorted(out.glob("*.md")) if out.is_dir() else []:  # pages other studies wrote here
        if f.name not in known:
            title = next((ln.lstrip("# ").strip() for ln in f.read_text().splitlines() if ln.startswith("#")), "")
            lines.append(f"- [{f.name}]({f.name}): {title}")
    p = out / "README.md"
    p.write_text("\n".join(lines) + "\n")
    return p
