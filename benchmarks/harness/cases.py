"""A robustness case's outcome, and the CLI run in-process: what every category of the
robustness suite (benchmarks/robustness.py and the modules beside it) classifies with.

Outcomes: ``accepted`` (valid input, right result), ``clear error`` (invalid input refused
with a TactileForceError naming it), ``valid refused`` (a false alarm), ``traceback`` (any
other exception, a CLI traceback or a wrong exit code), ``silent wrong`` (invalid input
accepted, a wrong value returned), ``hang`` (no answer in time), ``data lost`` (a fault cost
a complete sample or changed an input).
"""

from __future__ import annotations

import contextlib
import enum
import io
import json
import math
import sys
import threading
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np


class Outcome(str, enum.Enum):
    ACCEPTED = "accepted"
    CLEAR = "clear error"
    VALID_REFUSED = "valid refused"
    TRACEBACK = "traceback"
    SILENT_WRONG = "silent wrong"
    HANG = "hang"
    DATA_LOST = "data lost"


#: Outcomes a robust package never produces.
BAD = frozenset({Outcome.VALID_REFUSED, Outcome.TRACEBACK, Outcome.SILENT_WRONG, Outcome.HANG, Outcome.DATA_LOST})
_WORST = [Outcome.ACCEPTED, Outcome.CLEAR, Outcome.VALID_REFUSED, Outcome.HANG, Outcome.TRACEBACK,
          Outcome.SILENT_WRONG, Outcome.DATA_LOST]


@dataclass
class Verdict:
    outcome: Outcome
    detail: str = ""

    @property
    def ok(self) -> bool:
        return self.outcome not in BAD

    def __str__(self) -> str:
        return f"{self.outcome.value}: {self.detail}"


def worst(verdicts: list[Verdict]) -> Verdict:
    return max(verdicts, key=lambda v: _WORST.index(v.outcome))


def _tf_error() -> type[BaseException]:
    from tactile_force.edge.errors import TactileForceError

    return TactileForceError


def refusal(exc: BaseException, should_fail: bool | None, *, names: tuple[str, ...] = ()) -> Verdict:
    """Classify an exception: a TactileForceError with a message (naming ``names``) is a clear
    error when the input was bad (or may be), a false alarm when it was valid."""
    if not isinstance(exc, _tf_error()):
        return Verdict(Outcome.TRACEBACK, f"{type(exc).__name__}: {exc}"[:300])
    msg = str(exc)
    missing = [n for n in names if n not in msg]
    if not msg.strip() or missing:
        return Verdict(Outcome.TRACEBACK, f"unclear message (missing {missing}): {msg[:200]}")
    if should_fail is False:
        return Verdict(Outcome.VALID_REFUSED, msg[:300])
    return Verdict(Outcome.CLEAR, msg[:300])


def accepted(should_fail: bool | None, detail: str = "") -> Verdict:
    if should_fail:
        return Verdict(Outcome.SILENT_WRONG, f"accepted: {detail}"[:300])
    return Verdict(Outcome.ACCEPTED, detail[:300])


def with_timeout(fn: Callable[[], Verdict], timeout_s: float) -> Verdict:
    """Run ``fn`` in a thread; HANG when it does not return within ``timeout_s``."""
    box: list[Verdict] = []

    def run() -> None:
        try:
            box.append(fn())
        except BaseException as exc:  # noqa: BLE001 - every escape is classified
            box.append(Verdict(Outcome.TRACEBACK, f"{type(exc).__name__}: {exc}"[:300]))

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(timeout_s)
    if t.is_alive():
        return Verdict(Outcome.HANG, f"no answer in {timeout_s:g} s")
    return box[0]


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """``tactile-force ARGV`` in-process: (exit code, stdout, stderr); argparse's exit is caught."""
    from tactile_force.edge.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = int(main(list(argv)) or 0)
        except SystemExit as exc:
            rc = exc.code if isinstance(exc.code, int) else 2
        except Exception:  # what the console script would print: a traceback, exit 1
            traceback.print_exc(file=sys.stderr)
            rc = 1
    return rc, out.getvalue(), err.getvalue()


def cli_verdict(argv: list[str], want_rc: set[int], should_fail: bool, names: tuple[str, ...] = ()) -> Verdict:
    try:
        rc, out, err = run_cli(argv)
    except BaseException as exc:  # noqa: BLE001
        return Verdict(Outcome.TRACEBACK, f"{' '.join(argv)}: {type(exc).__name__}: {exc}"[:300])
    text = out + err
    if "Traceback" in text:
        return Verdict(Outcome.TRACEBACK, f"{' '.join(argv)}: printed a traceback")
    if rc == 0 and should_fail:
        return Verdict(Outcome.SILENT_WRONG, f"{' '.join(argv)}: exit 0")
    if rc not in want_rc:
        return Verdict(Outcome.TRACEBACK, f"{' '.join(argv)}: exit {rc}, expected {sorted(want_rc)}: {err[-200:]}")
    missing = [n for n in names if n not in text]
    if missing:
        return Verdict(Outcome.TRACEBACK, f"{' '.join(argv)}: message does not name {missing}: {err[-200:]}")
    return Verdict(Outcome.CLEAR if should_fail else Outcome.ACCEPTED, f"exit {rc}: {err.strip()[-160:]}")


# =============================================================================== frames on disk
def write_frame_png(path: Path, seed: int = 0, noise: bool = False) -> np.ndarray:
    """A 320x240x3 uint8 BGR frame (smooth, or incompressible noise) written as PNG."""
    import cv2

    rng = np.random.default_rng(seed)
    if noise:
        frame = rng.integers(0, 256, (320, 240, 3), dtype=np.uint8)
    else:
        frame = np.full((320, 240, 3), 100, np.uint8)
        frame[100:200, 60:180] = rng.integers(90, 140, 3, dtype=np.uint8)
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), frame)
    return frame


def make_dataset(root: Path, n: int = 1, forces: list[float] | None = None) -> Path:
    """An authors'-layout dataset of ``n`` synthetic frames with valid labels."""
    from tactile_force.edge.data.dataset import AuthorsDatasetWriter

    with AuthorsDatasetWriter(root) as w:
        for i in range(n):
            frame = np.full((320, 240, 3), 90 + i, np.uint8)
            w.write(frame, (forces or [1.0 + i] * n)[i], meta={"k": i})
    return root


def default_bundle_dir() -> Path:
    """The default bundle of the installed package (edge/models/default: the package's one answer)."""
    from tactile_force.edge.scene import default_bundle_path

    return default_bundle_path()


def toml_text(data: dict) -> str:
    """A TOML document for ``data`` (scalars, arrays of scalars, tables, arrays of tables)."""

    def scalar(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int):
            return str(v)
        if isinstance(v, float):
            return "nan" if v != v else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(scalar(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(k)} = {scalar(x)}" for k, x in v.items()) + "}"
        raise TypeError(type(v))

    lines: list[str] = []
    tables = {k: v for k, v in data.items() if isinstance(v, dict)}
    arrays = {k: v for k, v in data.items() if isinstance(v, list) and v and all(isinstance(x, dict) for x in v)}
    for k, v in data.items():
        if k not in tables and k not in arrays:
            lines.append(f"{json.dumps(k)} = {scalar(v)}")
    for k, v in tables.items():
        lines.append(f"[{json.dumps(k)}]")
        lines += [f"{json.dumps(kk)} = {scalar(vv)}" for kk, vv in v.items()]
    for k, rows in arrays.items():
        for row in rows:
            lines.append(f"[[{json.dumps(k)}]]")
            lines += [f"{json.dumps(kk)} = {scalar(vv)}" for kk, vv in row.items()]
    return "\n".join(lines) + "\n"
