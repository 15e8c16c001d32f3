"""Robustness categories of the authors' data files: force labels (force_N.txt) and the
recorder's meta.jsonl, each generated case probed through the public readers (benchmarks/robustness.py
runs them)."""

from __future__ import annotations

import json
import logging
import math
import re
from pathlib import Path

from hypothesis import strategies as st

from .harness.cases import (
    Outcome,
    Verdict,
    accepted,
    refusal,
    worst,
)
from .robustness_table import label_tokens

MAX_FORCE_N = 200.0


# =============================================================================== labels
#: label file contents every reader is tried on (robustness_cases.toml [values] label_tokens)
_LABEL_TOKENS = label_tokens()


def label_bytes() -> st.SearchStrategy[bytes]:
    """Contents of a force_N.txt: valid forces, odd numbers, odd tokens, junk and text."""
    good = st.floats(0.0, MAX_FORCE_N, allow_nan=False).map(lambda v: f"{v!r}\n".encode())
    numbers = st.floats(allow_nan=True, allow_infinity=True).map(lambda v: repr(v).encode())
    tokens = st.sampled_from(_LABEL_TOKENS)
    junk = st.binary(max_size=24)
    text = st.text(max_size=12).map(lambda s: s.encode("utf-8", "surrogatepass"))
    tail = st.tuples(st.one_of(tokens, good), st.one_of(junk, text)).map(lambda t: t[0] + b"\n" + t[1])
    return st.one_of(good, numbers, tokens, junk, text, tail)


def expected_label(data: bytes) -> float | None:
    """The label's force by the documented rule (docs/robustness.md), or None when invalid."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return None
    if "\x00" in text:
        return None
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    if re.match(r"[+-]?\d+,\d", first):  # a decimal comma: 1,08
        return None
    fields = [f for f in re.split(r"\s*[,;]\s*|\s+", first) if f]
    if not fields:
        return None
    values = []
    for f in fields:  # the force, then only numbers (no unit, no text)
        if set(f) - set("0123456789.eE+-"):
            return None
        try:
            values.append(float(f))
        except ValueError:
            return None
    v = values[0]
    return v if math.isfinite(v) and 0.0 <= v <= MAX_FORCE_N else None


class _Count(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def probe_label(root: Path, data: bytes, *, calib: bool = True) -> Verdict:
    """One label file through every reader: read_force_file, the dataset reader, the replay
    source (must warn once and yield truth None, never die) and quantize's --calib reader."""
    from tactile_force.edge.data.dataset import AuthorsDataset, read_force_file
    from tactile_force.edge.sources import ReplayFolderSource

    want = expected_label(data)
    bad = want is None
    label = root / "forces" / "force_0.txt"
    label.write_bytes(data)
    names = ("force_0.txt",)
    verdicts: list[Verdict] = []

    def value_check(v: float, who: str) -> Verdict:
        if bad:
            return accepted(True, f"{who} read {v!r} from {data[:30]!r}")
        if v != want:
            return Verdict(Outcome.SILENT_WRONG, f"{who} read {v!r}, the file says {want!r}")
        return Verdict(Outcome.ACCEPTED)

    for who, read in (("read_force_file", lambda: read_force_file(label)),
                      ("AuthorsDataset", lambda: AuthorsDataset(root).load(0).force_n)):
        try:
            verdicts.append(value_check(read(), who))
        except BaseException as exc:  # noqa: BLE001
            verdicts.append(refusal(exc, bad, names=names))
    # replay: never dies on a bad label; warns once per file; truth None
    log = logging.getLogger("tactile_force.edge.sources.files")
    h = _Count()
    log.addHandler(h)
    try:
        src = ReplayFolderSource(root, fps=None)
        frames = [src.read(), src.read()]
        src.close()
        if frames[0] is None:
            verdicts.append(Verdict(Outcome.SILENT_WRONG, "replay yielded no frame"))
        else:
            tf = frames[0]
            if bad:
                warned = [r for r in h.records if "force_0.txt" in r.getMessage()]
                if tf.truth_n is not None:
                    verdicts.append(Verdict(Outcome.SILENT_WRONG, f"replay truth {tf.truth_n!r} from a bad label"))
                elif len(warned) != 1 or "label_error" not in tf.meta:
                    verdicts.append(Verdict(Outcome.SILENT_WRONG, f"replay: {len(warned)} warnings, meta {tf.meta}"))
                else:
                    verdicts.append(Verdict(Outcome.CLEAR, warned[0].getMessage()[:200]))
            else:
                verdicts.append(value_check(tf.truth_n, "replay"))
    except BaseException as exc:  # noqa: BLE001
        verdicts.append(Verdict(Outcome.TRACEBACK, f"replay died: {type(exc).__name__}: {exc}"[:300]))
    finally:
        log.removeHandler(h)
    if calib:
        from tactile_force.export.calibration import CalibrationData

        try:
            forces = CalibrationData.from_path(root, "rgbmod", min_frames=1).forces
            verdicts.append(value_check(float(forces[0]), "quantize --calib"))
        except BaseException as exc:  # noqa: BLE001
            verdicts.append(refusal(exc, bad, names=names))
    return worst(verdicts)


# =============================================================================== meta.jsonl
@st.composite
def meta_bytes(draw) -> bytes:
    """A meta.jsonl: valid records, then maybe cut short, binary junk or a non-object line."""
    n = draw(st.integers(1, 4))
    lines = [json.dumps({"id": i, "timestamp_ns": draw(st.integers(0, 2**62))}).encode() + b"\n" for i in range(n)]
    data = b"".join(lines)
    op = draw(st.sampled_from(["none", "truncate", "junk", "line", "binary"]))
    if op == "truncate":
        data = data[:draw(st.integers(0, len(data)))]
    elif op == "junk":
        data += draw(st.binary(min_size=1, max_size=16))
    elif op == "line":
        bad = draw(st.sampled_from([b"[1, 2]", b"42", b'"id"', b'{"id": "3"}', b'{"id": -1}', b'{"id": true}',
                                    b'{"noid": 1}', b"{", b"null"]))
        k = draw(st.integers(0, n))
        parts = data.split(b"\n")
        parts.insert(k, bad)
        data = b"\n".join(parts)
    elif op == "binary":
        data = draw(st.binary(min_size=1, max_size=40))
    return data


def expected_meta(data: bytes) -> int | None:
    """None when every non-blank line is a JSON object with an integer id >= 0, else the
    1-based number of the first bad line."""
    for k, raw in enumerate(data.split(b"\n"), start=1):
        if not raw.strip():
            continue
        try:
            rec = json.loads(raw.decode("utf-8"))
        except ValueError:
            return k
        n = rec.get("id") if isinstance(rec, dict) else None
        if not isinstance(n, int) or isinstance(n, bool) or n < 0:
            return k
    return None


def probe_meta(root: Path, data: bytes) -> Verdict:
    from tactile_force.edge.data.dataset import AuthorsDataset

    (root / "meta.jsonl").write_bytes(data)
    bad_line = expected_meta(data)
    try:
        ds = AuthorsDataset(root)
    except BaseException as exc:  # noqa: BLE001
        return refusal(exc, bad_line is not None, names=("meta.jsonl", f"line {bad_line}") if bad_line else ())
    return accepted(bad_line is not None, f"meta ids {sorted(ds.meta)}")
