"""``tactile-force bench``'s outputs: the results table (plain text for the CLI, report.md), the
error-against-latency plot (pareto.png) and report.json, written atomically."""

from __future__ import annotations

import json
import math
from pathlib import Path

from .bench_contract import PLOT_PNG, REPORT_JSON, REPORT_MD, BenchReport, BundleResult

# ----------------------------------------------------------------------------- output
VERDICT_TEXT = {"PASS": "PASS", "OVER_BUDGET": "over budget", "MACHINE_BUSY": "machine busy (no verdict)",
                "NO_READINGS": "no force on the bench frames (no verdict)",
                "TOO_FEW_READINGS": "too few readings for a p99 (no verdict)"}


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def cadence_label(report: BenchReport) -> str | None:
    """``"60 fps"`` when the bundles were measured at one cadence, ``"cadence"`` at several,
    None when none was (back to back only)."""
    fps = sorted({b.cadence.fps for b in report.bundles if b.cadence is not None})
    if not fps:
        return None
    return f"{fps[0]:g} fps" if len(fps) == 1 else "cadence"


def _share(v: float | None) -> str:
    return "-" if v is None else f"{100 * v:.1f} %"


def table_rows(report: BenchReport) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the results table (one row per bundle): the stages and total back to
    back (b2b), the total and process CPU at the cadence when measured."""
    at = cadence_label(report)
    head = ["bundle", "variant", "precision", "gate p50", "depth p50", "inference p50", "b2b total p50",
            "b2b total p99"]
    if at is not None:
        head += [f"{at} total p50", f"{at} total p99", f"{at} CPU", f"{at} bare graph p99"]
    head += ["RE (here)", "MAE N (here)", "RE (manifest)", "verdict"]
    rows = []
    for b in report.bundles:
        st = b.stages_ms
        e = b.error
        row = [b.name, b.variant, b.precision, _ms(st["gate"].p50 if "gate" in st else None),
               _ms(st["depth"].p50 if "depth" in st else None),
               _ms(st["inference"].p50 if "inference" in st else None), _ms(b.total_ms.p50), _ms(b.total_ms.p99)]
        if at is not None:
            c = b.cadence
            row += ["-", "-", "-", "-"] if c is None else [
                _ms(c.total_ms.p50), _ms(c.total_ms.p99), _share(c.cpu_share),
                _ms(c.bare_ms.p99 if c.bare_ms is not None else None)]
        row += ["-" if e is None or e.re_mean is None else f"{e.re_mean:.3f}",
                "-" if e is None else f"{e.mae_mean:.3f}", "-" if b.manifest_re is None else f"{b.manifest_re:.3f}",
                VERDICT_TEXT.get(b.verdict, b.verdict)]
        rows.append(row)
    return head, rows


def _measured_how(report: BenchReport) -> str:
    """What the table's columns are, in one sentence (text table and report.md)."""
    at = cadence_label(report)
    ns = sorted({b.cadence.total_ms.n for b in report.bundles if b.cadence is not None})
    b2b = (f"latency in ms through ForceRuntime, frames in contact, {report.threads} thread(s): stages and b2b "
           f"total with frames back to back ({report.frames} frames)")
    if at is None:
        return b2b + f"; budget: total p99 <= {report.budget_ms:g} ms"
    return (b2b + f"; {at}: frames arriving at the sensor's cadence, the source sleeping until each is due "
            f"({'/'.join(str(n) for n in ns)} readings), CPU = process CPU time / wall time meanwhile (of one core), "
            f"bare graph = the bundle's graph alone in a bare onnxruntime session at the same cadence (the floor); "
            f"budget: total p99 at {at} <= {report.budget_ms:g} ms")


def _missed_lines(report: BenchReport) -> list[str]:
    """What the table alone does not say: frames skipped at the cadence, and bundles whose
    graph alone misses the budget at the cadence (no runtime around it can meet it here)."""
    out = [f"{b.name}: {b.cadence.missed} frame(s) skipped at {b.cadence.fps:g} fps (the runtime was late for them; "
           "no reading measured for them)" for b in report.bundles if b.cadence is not None and b.cadence.missed]
    for b in report.bundles:
        c = b.cadence
        if b.verdict != "PASS" and c is not None and c.bare_ms is not None and c.bare_ms.p99 is not None \
                and c.bare_ms.p99 > report.budget_ms:
            out.append(f"{b.name}: its graph alone, in a bare onnxruntime session at {c.fps:g} fps, takes p99 "
                       f"{c.bare_ms.p99:.3f} ms > the {report.budget_ms:g} ms budget: no runtime around a network of "
                       "this size holds the budget on this host; try a smaller one (the shipped default "
                       "edge/models/default, or tactile-force compress)")
    return out


def text_table(report: BenchReport) -> str:
    """The results as aligned plain text (what the CLI prints), machine state per bundle after it."""
    head, rows = table_rows(report)
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(head)]
    out = ["  ".join(h.ljust(w) for h, w in zip(head, widths))]
    out += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    out.append(_measured_how(report))
    out += _missed_lines(report)
    for b in report.bundles:
        for i, a in enumerate(b.attempts, 1):
            out.append(f"{b.name} attempt {i}: total p99 {_judged(b)}{_ms(a.total_p99_ms)} ms; {a.machine.line()}")
        if b.verdict == "TOO_FEW_READINGS":
            out.append(f"{b.name}: {b.note}")
    out.append(f"verdict: {VERDICT_TEXT.get(report.verdict, report.verdict)}")
    return "\n".join(out)


def _judged(b: BundleResult) -> str:
    return f"at {b.cadence.fps:g} fps " if b.cadence is not None else ""


def markdown(report: BenchReport) -> str:
    """report.md: command, commit, machine, the table, per-bin error, machine state per attempt."""
    from .harness.paths import source_commit

    head, rows = table_rows(report)
    m = report.machine
    how = _measured_how(report)
    lines = ["# tactile-force bench", "", f"Command: `{report.command}`" if report.command else "",
             f"Commit: {source_commit()}", f"Machine: {m.line()}.",
             f"At start: {m.background_load}.",
             *([f"Per-frame image work: {report.image_path}."] if report.image_path else []), "",
             f"{how[0].upper()}{how[1:]}. In-memory sources; total = frame arrival -> reading. "
             f"Verdict: **{VERDICT_TEXT.get(report.verdict, report.verdict)}**.",
             *([""] + [f"- {line}" for line in _missed_lines(report)] if _missed_lines(report) else []), "",
             "| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    for b in report.bundles:
        lines += ["", f"## {b.name}", "", f"Path: `{b.path}`." + (f" Note: {b.note}." if b.note else "")]
        for i, a in enumerate(b.attempts, 1):
            lines.append(f"- attempt {i}: total p99 {_judged(b)}{_ms(a.total_p99_ms)} ms; {a.machine.line()}")
        if b.error is not None:
            e = b.error
            lines += ["", f"Error on `{e.data}` (background `{e.background}`): {e.n} CNN readings of "
                      f"{e.frames_with_truth} frames with truth; {e.missed} with truth >= 1 N got no force.", "",
                      "| force bin (N) | n | RE | MAE (N) |", "|---|---|---|---|"]
            lines += [f"| {k} | {s.n} | {'-' if s.re_mean is None else f'{s.re_mean:.3f}'} | {s.mae_mean:.3f} |"
                      for k, s in e.per_bin.items()]
    return "\n".join(lines).replace("\n\n\n", "\n\n") + "\n"


def plot(report: BenchReport, path: Path) -> Path:
    """Error against the judged p99 latency (at the cadence when measured), one point per
    bundle, its back-to-back p99 as a grey mark joined to it, the budget line (OpenCV)."""
    from tactile_force.edge.report.plots import ParetoPoint, error_vs_latency

    pts = []
    for b in report.bundles:
        measured = b.error is not None and b.error.re_mean is not None
        err = b.error.re_mean if measured and b.error is not None else b.manifest_re
        p99 = b.judged_ms.p99
        pts.append(ParetoPoint(b.name, p99 if p99 is not None else math.nan, err, measured,
                               b.total_ms.p99 if b.cadence is not None else None))
    at = cadence_label(report)
    title = f"{report.machine.cpu}, {report.threads} thread(s)" + (f", p99 at {at}" if at else "")
    return error_vs_latency(pts, report.budget_ms, path, title=title, also="back to back")


def write_json(path: Path, obj: object) -> Path:
    """``obj`` as indented JSON at ``path``, replaced atomically (a reader never sees half a file)."""
    from tactile_force.edge.files.atomic import staged_file

    with staged_file(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2) + "\n")
    return path


def write_report(report: BenchReport, out: Path) -> list[Path]:
    """Write report.json, report.md and pareto.png into the folder ``out`` (made if missing;
    the CLI passes a hidden staging folder that becomes ``--out`` when all three are written)."""
    out.mkdir(parents=True, exist_ok=True)
    js = write_json(out / REPORT_JSON, report.to_json())
    md = out / REPORT_MD
    md.write_text(markdown(report))
    return [js, md, plot(report, out / PLOT_PNG)]
