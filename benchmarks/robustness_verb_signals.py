"""Verb promises: interruption. SIGINT / SIGTERM during a verb's work leave no half result and exit
130 (a subprocess per case)."""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from .harness.cases import (
    Outcome,
    Verdict,
    worst,
)
from .robustness_inputs import TF_CLI, digest

# ================================================================== shared inputs
from .robustness_verb_base import (
    START_S,
    STOP_S,
    VERBS,
    Case,
    Cases,
    Inputs,
    Verb,
    _csv_lines,
    _staging,
    _Stderr,
    leftovers,
)

#: is the verb at work yet? (output folder, stderr lines so far, an earlier result there)
AtWork = Callable[[Path, list[str], bool], bool]



def _writing(out: Path, previous: bool) -> list[Path]:
    """Where a verb writes its result: its hidden staging folder(s), else (no earlier result
    there) ``out`` itself."""
    return _staging(out) + ([] if previous else [out])


#: verb -> is it at work? (its --out, its stderr lines so far, whether --out holds an earlier result)


_AT_WORK: dict[str, AtWork] = {
    "bench": lambda out, err, previous: any(ln.startswith("bench:") for ln in err),
    "study": lambda out, err, previous: any(ln.startswith("fp32:") for ln in err),
    "synth": lambda out, err, previous: any(list((s / "images").glob("*.png")) for s in _writing(out, previous)),
    "demo": lambda out, err, previous: any(_csv_lines(s / "readings.csv") > 3 for s in _writing(out, previous)),
    "run": lambda out, err, previous: _csv_lines(out) > 5,
    "compress": lambda out, err, previous: bool(list((out / "work").glob("teacher-*.npy"))),
}


def probe_signal(argv: list[str], out: Path, sig: int, at_work: AtWork, previous: bool,
                 check: Callable[[Path], str] | None = None) -> Verdict:
    """``tactile-force ARGV`` in a subprocess, sent ``sig`` one second after it is at work.
    Expected: exit 128 + sig (or death by the signal), no traceback, no hidden staging left, and
    ``out`` absent (``previous``: the earlier result byte for byte). ``check(out)``: what is
    wrong with what was left ('' when fine) for a verb that keeps an output by design."""
    name = signal.Signals(sig).name
    before = digest(out)
    proc = subprocess.Popen([sys.executable, str(TF_CLI), *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    err = _Stderr(proc)
    try:
        end = time.monotonic() + START_S
        while time.monotonic() < end and proc.poll() is None and not at_work(out, err.lines, previous):
            time.sleep(0.05)
        if proc.poll() is not None:
            return Verdict(Outcome.TRACEBACK, f"{name}: it ended (exit {proc.returncode}) before the signal: "
                                              f"{err.text()[-200:]}")
        if not at_work(out, err.lines, previous):
            proc.kill()
            proc.wait()
            return Verdict(Outcome.HANG, f"{name}: not at work within {START_S:g} s")
        time.sleep(1.0)
        proc.send_signal(sig)
        proc.wait(timeout=STOP_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        return Verdict(Outcome.HANG, f"{name}: did not stop within {STOP_S:g} s")
    text = err.text()
    rc = proc.returncode
    verdicts: list[Verdict] = []
    if "Traceback" in text:
        verdicts.append(Verdict(Outcome.TRACEBACK, f"{name}: printed a traceback: {text[-200:]}"))
    if rc == 0:
        verdicts.append(Verdict(Outcome.SILENT_WRONG, f"{name}: exit 0 after the signal (a partial result as success)"))
    elif rc not in (128 + sig, -sig):
        verdicts.append(Verdict(Outcome.TRACEBACK, f"{name}: exit {rc}, expected {128 + sig}: {text[-200:]}"))
    if previous and digest(out) != before:
        verdicts.append(Verdict(Outcome.DATA_LOST, f"{name}: the earlier result in {out.name} changed or vanished"))
    elif check is not None:
        if problem := check(out):
            verdicts.append(Verdict(Outcome.SILENT_WRONG, f"{name}: {problem}"))
    elif not previous and os.path.lexists(out):
        verdicts.append(Verdict(Outcome.SILENT_WRONG, f"{name}: a half-made --out {out.name} was left: "
                                                      f"{sorted(p.name for p in out.iterdir())[:6]}"))
    if left := leftovers(out):
        verdicts.append(Verdict(Outcome.SILENT_WRONG, f"{name}: hidden staging left: {left}"))
    if not verdicts:
        verdicts.append(Verdict(Outcome.CLEAR, f"{name}: exit {rc}, "
                                               + ("the earlier result kept" if previous else "nothing half-made")))
    return worst(verdicts)


def _complete_csv(out: Path) -> str:
    """What is wrong with a readings CSV a stopped run left ('' when every row is whole)."""
    import csv

    if not out.is_file():
        return ""
    text = out.read_text()
    rows = list(csv.reader(text.splitlines()))
    if not rows:
        return f"{out.name} is empty"
    cut = [k for k, row in enumerate(rows) if len(row) != len(rows[0])]
    if cut or not text.endswith("\n"):
        return f"{out.name}: row(s) {(cut or [len(rows) - 1])[:3]} cut short"
    return ""


def _no_finished_look(out: Path) -> str:
    """compress keeps work/ (a rerun resumes) but never a bundle or summary of an unfinished run,
    nor a hidden temporary file."""
    try:
        from tactile_force.edge.files.atomic import OUTPUT_MARK
    except ImportError:  # a package from before result records
        OUTPUT_MARK = ""
    made = [n for n in ("bundle", "compress.json") if (out / n).exists()]
    hidden = [str(q.relative_to(out)) for q in out.rglob(".*") if q.name != OUTPUT_MARK] if out.is_dir() else []
    return (f"an interrupted compress left {made} (looks finished)" if made else
            f"an interrupted compress left temporary files {hidden[:3]}" if hidden else "")


def signal_cases(inputs: Inputs, examples: int) -> Cases:
    """SIGINT and SIGTERM during bench, study, synth, demo (SIGINT into a new --out, SIGTERM
    with --force over an earlier result), run (a replay paced at 20 fps) and compress."""
    cases: list[Case] = []
    for name, spec in VERBS.items():
        if spec.torch and inputs.fp32 is None:
            continue

        def fresh(spec: Verb = spec) -> Verdict:
            out = inputs.folder(spec.name) / "r"
            return probe_signal(spec.long_argv(inputs, out), out, signal.SIGINT, _AT_WORK[spec.name], False)

        def over_earlier(spec: Verb = spec) -> Verdict:
            out = inputs.earlier(spec.name, inputs.folder(spec.name) / "r")
            return probe_signal(spec.long_argv(inputs, out) + ["--force"], out, signal.SIGTERM, _AT_WORK[spec.name],
                                True)

        cases += [(f"SIGINT during {name} (new --out)", fresh),
                  (f"SIGTERM during {name} --force (over its earlier result)", over_earlier)]

    def run(sig: int) -> Verdict:
        out = inputs.folder("run") / "r.csv"
        return probe_signal(["run", "--source", str(inputs.replay), "--fps", "20", "--out", str(out)], out, sig,
                            _AT_WORK["run"], False, check=_complete_csv)

    def compress(sig: int) -> Verdict:
        out = inputs.folder("compress") / "c"
        return probe_signal(["compress", str(inputs.teacher), "--frames", str(inputs.replay), "--out", str(out),
                             "--ladder", "0.125x8", "--epochs", "100000", "--threads", "1"], out, sig,
                            _AT_WORK["compress"], False, check=_no_finished_look)

    for sig in (signal.SIGINT, signal.SIGTERM):
        cases.append((f"{sig.name} during run (replay at --fps 20)", functools.partial(run, sig)))
    if inputs.fp32 is not None:
        for sig in (signal.SIGINT, signal.SIGTERM):
            cases.append((f"{sig.name} during compress", functools.partial(compress, sig)))
    return cases, inputs.note
