"""Verb promises: the statistics floor of a p99 verdict and labelled data judged before any work."""

from __future__ import annotations

import functools
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .harness.cases import (
    Outcome,
    Verdict,
    run_cli,
)
from .robustness_inputs import guarded

# ================================================================== shared inputs
from .robustness_verb_base import FLOOR, Cases, Inputs, _csv_lines, _either, _with_leftovers


def probe_floor(inputs: Inputs, verb: str, frames: int) -> Verdict:
    """``bench`` / ``study`` with ``--frames N`` (bench: and ``--cadence-frames N``, the readings
    its verdict rests on, at the default 60 fps): below the floor no verdict (exit 1, 'too few
    readings' printed and in the report); at the floor a verdict."""
    out = inputs.folder(f"{verb}_floor") / "r"
    if verb == "bench":
        argv = ["bench", "--bundle", str(inputs.bundle), "--frames", str(frames), "--cadence-frames", str(frames),
                "--repeats", "1", "--budget-ms", "1000", "--out", str(out)]
    else:
        assert inputs.fp32 is not None
        argv = ["study", str(inputs.fp32), "--data", str(inputs.data), "--frames", str(frames), "--budget-ms", "1000",
                "--quick", "--max-configs", "0", "--sensitivity-nodes", "0", "--out", str(out)]
    what = f"{verb} --frames {frames}" + (f" --cadence-frames {frames}" if verb == "bench" else "")
    try:
        rc, stdout, stderr = run_cli(argv)
    except BaseException as exc:  # noqa: BLE001 - classified
        return Verdict(Outcome.TRACEBACK, f"{what}: {type(exc).__name__}: {exc}"[:300])
    if "Traceback" in stdout + stderr:
        return Verdict(Outcome.TRACEBACK, f"{what}: printed a traceback")
    if rc not in (0, 1):
        return Verdict(Outcome.TRACEBACK, f"{what}: exit {rc}: {stderr[-200:]}")
    report = out / ("report.json" if verb == "bench" else "study.json")
    text = out / ("report.md" if verb == "bench" else "study.md")
    try:
        raw = json.loads(report.read_text())
        page = text.read_text()
    except (OSError, ValueError) as exc:
        return Verdict(Outcome.TRACEBACK, f"{what}: exit {rc} without a readable report: {exc}")
    verdict = raw.get("verdict") if verb == "bench" else raw.get("recommended")
    few = "too few readings"
    if frames < FLOOR:
        if rc == 0 or (verdict not in ("TOO_FEW_READINGS", None)):
            return Verdict(Outcome.SILENT_WRONG, f"{what}: exit {rc}, verdict {verdict!r} from {frames} readings")
        missing = [w for w, t in (("printed", stdout + stderr), ("report", page)) if few not in t]
        if missing:
            return Verdict(Outcome.TRACEBACK, f"{what}: no verdict but '{few}' missing from {missing}")
        return Verdict(Outcome.CLEAR, f"{what}: exit 1, {few}")
    if few in stdout + stderr + page or verdict in ("TOO_FEW_READINGS", None):
        return Verdict(Outcome.VALID_REFUSED, f"{what}: no verdict from {frames} readings (exit {rc}, {verdict!r})")
    return Verdict(Outcome.ACCEPTED, f"{what}: exit {rc}, verdict {verdict}")


def floor_cases(inputs: Inputs, examples: int) -> Cases:
    """bench and study with --frames 1, 5, 50, 99 (no verdict) and 100 (a verdict)."""
    verbs = ["bench"] + (["study"] if inputs.fp32 is not None else [])
    return [(f"{v} --frames {n}", functools.partial(probe_floor, inputs, v, n))
            for v in verbs for n in (1, 5, 50, FLOOR - 1, FLOOR)], inputs.note


def _bad_images() -> list[tuple[str, Callable[[Path], None], bool | None]]:
    """(what, writer turning the press image at a path into a bad one, must every verb refuse
    it: None = either answer fits)."""
    import cv2

    def png(change: Callable[[np.ndarray], np.ndarray]) -> Callable[[Path], None]:
        def write(p: Path) -> None:
            img = cv2.imread(str(p), cv2.IMREAD_COLOR)
            p.unlink()
            cv2.imwrite(str(p), change(img))
        return write

    def dangling(p: Path) -> None:
        p.unlink()
        p.symlink_to(p.parent / "gone" / p.name)

    def empty(p: Path) -> None:
        p.write_bytes(b"")

    return [("grayscale PNG", png(lambda x: cv2.cvtColor(x, cv2.COLOR_BGR2GRAY)), True),
            ("RGBA PNG", png(lambda x: cv2.cvtColor(x, cv2.COLOR_BGR2BGRA)), True),
            ("16-bit PNG", png(lambda x: x.astype(np.uint16) * 257), True),
            ("160x120 PNG (wrong size)", png(lambda x: cv2.resize(x, (120, 160), interpolation=cv2.INTER_AREA)), True),
            ("480x640 PNG (wrong size)", png(lambda x: cv2.resize(x, (640, 480))), True),
            ("a dangling symlink", dangling, True),
            ("a zero-byte PNG", empty, True),
            ("240x320 PNG (the press as a DIGIT's landscape image, which the replay source turns upright)",
             png(lambda x: cv2.rotate(x, cv2.ROTATE_90_CLOCKWISE)), None)]


BAD_ID = 6  # the bad frame sits in the middle: a verb reading lazily has done work before it


def probe_labelled(inputs: Inputs, verb: str, write_bad: Callable[[Path], None], must_refuse: bool | None) -> Verdict:
    """One bad image among the labelled frames: exit 2 naming the file, nothing written."""
    d = inputs.folder(f"{verb}_data")
    data = Path(shutil.copytree(inputs.data, d / "presses", symlinks=True))
    bad = data / "images" / f"{BAD_ID}.png"
    write_bad(bad)
    out = d / ("r.csv" if verb == "run" else "r")
    argv = {"bench": lambda: ["bench", "--bundle", str(inputs.bundle), "--data", str(data), "--frames", "100",
                              "--fps", "200", "--cadence-frames", "100", "--repeats", "1", "--budget-ms", "1000",
                              "--out", str(out)],
            "study": lambda: ["study", str(inputs.fp32), "--data", str(data), "--frames", "5", "--quick",
                              "--max-configs", "0", "--sensitivity-nodes", "0", "--out", str(out)],
            "calibrate-force": lambda: ["calibrate-force", str(inputs.bundle), "--data", str(data), "--out", str(out)],
            "run": lambda: ["run", "--source", str(data), "--out", str(out)]}[verb]()
    ok_rc = {0, 1} if verb in ("bench", "study") else {0}
    v = guarded(argv, [data], True, (bad.name,)) if must_refuse else _either(argv, [data], ok_rc, (bad.name,))
    if v.outcome is Outcome.CLEAR and out.exists():
        n = _csv_lines(out) - 1 if verb == "run" else None
        return Verdict(Outcome.TRACEBACK, f"refused after work: {out.name} was written"
                                          + (f" ({n} readings)" if n is not None else "") + f"; {v.detail}")
    return _with_leftovers(v, out)


def labelled_cases(inputs: Inputs, examples: int) -> Cases:
    """bench --data, study --data, calibrate-force --data and run --source on labelled frames
    holding one bad image: exit 2 naming the file before any work."""
    verbs = ["bench", "calibrate-force", "run"] + (["study"] if inputs.fp32 is not None else [])
    return [(f"{verb}: {what}", functools.partial(probe_labelled, inputs, verb, write, must))
            for what, write, must in _bad_images() for verb in verbs], inputs.note
