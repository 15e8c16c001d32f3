"""``tactile-force bundle show|verify``: inspect a model bundle on the robot (no torch needed).

``verify`` exits 0 when the bundle loads as every loader loads it
(:func:`~tactile_force.edge.bundle.store.load_bundle`: no file of the bundle resolves outside it
(symbolic links), the manifest and its records validate (ranges ordered, a plain name, a depth
record only where the variant reads depth), the sha256 matches, the manifest's claims agree
with the graph: :func:`.graph_facts.manifest_problems`, no ``onnx`` package needed: the
precision, int8-static / int8-dynamic / fp16 / fp32, from its op types and weights; the network
input size against ``architecture.input_scale`` / ``network_input_hw`` and the inputs'
reduction; the inputs against the variant), the graph fits the frame contract its manifest
declares in ONNX Runtime (inputs, variant) and one run of the largest batch a runtime sends (16 frames,
one per sensor) gives 16 finite forces; 1 when any check fails (the reasons on one line).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def configure_bundle(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = ("Inspect a model bundle.\n\n"
                     "  show PATH     print the manifest summary (--json for all of it, --nodes for node names)\n"
                     "  verify PATH   refuse files linked from outside the bundle, validate the manifest, check\n"
                     "                the sha256, load the graph in ONNX Runtime against the frame contract, check\n"
                     "                the manifest's precision, input scale and variant inputs against the graph\n"
                     "                and run it once; exit 1 if anything is off")
    p.add_argument("action", choices=("show", "verify"))
    p.add_argument("path", type=Path, help="bundle folder, or NAME.onnx with its NAME.json")
    p.add_argument("--json", action="store_true", help="show: print the full manifest as JSON")
    p.add_argument("--nodes", action="store_true", help="show: list the graph's node names and op types (needs onnx)")


def main_bundle(args: argparse.Namespace) -> int:
    from ..bundle.store import load_bundle
    from ..errors import BundleError

    if args.action == "verify":
        try:
            return _verify(args.path)
        except BundleError as exc:
            print(f"tactile-force bundle verify: FAILED: {exc}", file=sys.stderr)
            return 1
    b = load_bundle(args.path)
    m = b.manifest
    if args.json:
        print(m.to_json(), end="")
        return 0
    for line in describe_manifest(b):
        print(line)
    if args.nodes:
        from ..errors import require

        onnx = require("onnx", "export", "Listing graph nodes")
        for n in onnx.load(str(b.onnx_path)).graph.node:
            print(f"  {n.op_type:<18} {n.name}")
    return 0


def describe_manifest(b) -> list[str]:  # b: Bundle
    """Human summary of a bundle's manifest, one line per section present."""
    m = b.manifest
    lines = [f"bundle    {b.path}  (sha256 {m.sha256[:16]}... verified, manifest format {m.format_version})",
             f"variant   {m.variant.value}   precision {m.precision.value}"]
    lines += [f"input     {s.name}: {s.kind.value} {s.shape} {s.dtype} {s.layout} {s.colour_order}" for s in m.inputs]
    lines.append(f"output    {m.output.name}: {m.output.shape} {m.output.dtype} [{m.output.unit}]")
    if m.preprocessing:
        lines.append(f"graph     {'; '.join(m.preprocessing)}")
    a = m.architecture
    lines.append(f"network   {a.family} width {a.width}, input scale {a.input_scale}, input {a.network_input_hw}, "
                 f"{a.gmacs if a.gmacs is not None else '?'} GMACs, head folded: {a.head_folded}")
    if m.depth:
        lines.append(f"depth     mapping {m.depth.mapping}, mode {m.depth.mode}")
    if m.parity:
        lines.append(f"parity    max |ORT - torch| {m.parity.max_abs_diff_n:.2e} N on {m.parity.frames} frames")
    if m.quantization:
        q = m.quantization
        lines.append(f"quant     {q.format}, method {q.method or '-'}, per-channel {q.per_channel}, "
                     f"kept float {q.kept_float}")
    if m.error:
        e = m.error
        if e.vs_truth:
            lines.append(f"error     vs labels RE {_num(e.vs_truth.re_mean)} +- {_num(e.vs_truth.re_std)}, "
                         f"MAE {_num(e.vs_truth.mae_mean)} N ({e.vs_truth.n} frames of {e.data or '?'})")
        if e.vs_fp32:
            lines.append(f"error     vs fp32 max {e.vs_fp32.max_abs_diff_n:.4f} N, "
                         f"mean {e.vs_fp32.mean_abs_diff_n:.4f} N")
        if e.vs_teacher:
            lines.append(f"error     vs teacher RE {_num(e.vs_teacher.re_mean)}, MAE {_num(e.vs_teacher.mae_mean)} N")
    if m.force_calibration:
        c = m.force_calibration
        lines.append(f"calib     {c.method} force calibration, {len(c.raw_n)} knots, fitted on {c.frames} frames "
                     f"({c.data or '?'})")
    lines += data_stats_lines(m)
    lines += interval_lines(m)
    p = m.provenance
    lines.append(f"weights   trained on {p.trained_on}; checkpoint {p.checkpoint or '-'}"
                 + (f"; quantized from {p.quantized_from.bundle}" if p.quantized_from else "")
                 + (f"; calibrated from {p.calibrated_from.bundle}" if p.calibrated_from else ""))
    if p.note:
        lines.append(f"note      {p.note}")
    return lines


def interval_lines(m) -> list[str]:  # m: Manifest
    """Every reading's error bar (manifest ``interval``), one line."""
    iv = m.interval
    if iv is None:
        return ["interval  NONE: every reading's interval is 'unknown' (fit one: calibrate-force, or "
                "python -m benchmarks.interval_fit BUNDLE)"]
    if iv.model_sha256 and m.sha256 and iv.model_sha256 != m.sha256:
        return [f"interval  fitted for ANOTHER model ({iv.model_sha256[:12]}...): not applied, readings 'unknown'"]
    qs = [b.q for b in iv.bins if b.q is not None]
    unknown = sum(b.q is None for b in iv.bins)
    span = f"+- {min(qs):.3f} to {max(qs):.3f} x max(estimate, {iv.scale_floor_n:g} N)" if qs else "unknown everywhere"
    return [f"interval  {iv.coverage:g} coverage, {span}, {len(iv.bins)} bin(s)"
            + (f" ({unknown} unknown)" if unknown else "") + f", split conformal on {iv.n} frames ({iv.data or '?'})"]


def data_stats_lines(m) -> list[str]:  # m: Manifest
    """What the bundle's data statistics switch on (the runtime's honesty checks), one line."""
    d = m.data_stats
    if d is None:
        why = m.data_stats_missing or "none recorded by the tool that wrote this bundle"
        return [f"data      NO data statistics ({why}): out-of-distribution and contact-size checks OFF"]
    contact = ("contact-size check on" if d.contact_measured
               else "contact-size check OFF (no no-contact background was given)")
    return [f"data      statistics of {d.frames} frames ({d.source}): out-of-distribution check on, {contact}"]


def _num(x: float | None) -> str:
    return "n/a" if x is None or x != x else f"{x:.3f}"


def _verify(path: Path) -> int:
    import numpy as np

    from ..errors import BundleError
    from ..frames import MAX_BATCH
    from ..model.onnx_model import OnnxForceModel

    # load_bundle (in OnnxForceModel) makes the checks every loader makes: files inside the
    # bundle, the manifest and its records, the sha256, the manifest's claims against the graph
    # (store.check_bundle_files); ONNX Runtime then checks the graph contract (inputs, variant)
    model = OnnxForceModel(path, warmup=0)
    try:
        b = model.bundle
        rgb = np.zeros((MAX_BATCH, 320, 240, 3), np.uint8) if model.rgb_name else None
        depth = np.zeros((MAX_BATCH, 320, 240, 1), np.uint8) if model.needs_depth else None
        out = model.predict(rgb, depth)
        if out.shape != (MAX_BATCH,) or not np.all(np.isfinite(out)):
            raise BundleError(f"{b.onnx_path}: a batch of {MAX_BATCH} blank frames gave {out!r}; "
                              "expected finite forces (N), one per frame")
    finally:
        model.close()
    a = b.manifest.architecture
    print(f"ok: {b.path} ({b.variant}, {b.manifest.precision.value}) manifest valid, sha256 matches, files inside "
          f"the bundle, graph fits the frame contract, its ops and weights are {b.manifest.precision.value}, its "
          f"inputs are the variant's at input scale {a.input_scale:g} ({a.network_input_hw[0]} x "
          f"{a.network_input_hw[1]}), runs, output float32 N")
    return 0
