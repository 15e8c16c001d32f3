"""The one reader of force labels (``forces/force_N.txt``) and of ``meta.jsonl``.

Every reader of the authors' layout (the dataset reader, the replay source, quantize
``--calib``, ``record``'s resume) goes through this module, so a label is valid or not
the same way everywhere:

* the file is read as bytes and decoded as UTF-8 (a BOM is allowed);
* its first non-blank line starts with a plain decimal number with a decimal *point*
  (``1.08``, ``2e-3``, ``+4``; no ``nan``, ``inf``, ``1_000`` or hex), optionally followed
  by more numbers separated by white space, a comma or a semicolon, and further lines (the
  authors' files hold 10 floats, one a line);
* a decimal comma (``1,08``: digits, a comma, digits, as the first field) and a unit
  (``1.08 N``, ``1.08N``, ``108 g``) are errors naming the file: the number is always in
  newtons, written alone;
* the number is a normal force in newtons with ``0 <= F <= MAX_FORCE_N``.

A labelled set whose forces look like another unit (:func:`unit_problem`: most of them
above what a gel measures, or all below 1 N) is warned about where the set is read.

0 N is allowed (no-contact frames). Negative forces and forces above ``MAX_FORCE_N``
(200 N: ten times the paper's 0-20 N range and 4.5 times the largest real grasp in the
shared data, 44.5 N) are refused: they are gauge offsets, wrong units (grams written as
newtons) or garbage, never a grasp a DIGIT or GelSight Mini can measure.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

from ..errors import DatasetError

#: Largest force a label may hold, N (see the module docstring for why).
MAX_FORCE_N = 200.0

_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_DECIMAL_COMMA = re.compile(r"[+-]?\d+,\d")
_UNIT = re.compile(r"(?i)(?:k?n|newtons?|m?n|k?g|gf|kgf|lbf?|lbs|oz)")
_EXPECTED = f"expected UTF-8 text whose first line is the normal force in N, 0..{MAX_FORCE_N:g}"


class LabelError(DatasetError, ValueError):
    """A force label or a ``meta.jsonl`` line is missing, unreadable or out of range."""


def check_force(value: float, where: str) -> float:
    """``value`` (N) if it is a finite force in ``0..MAX_FORCE_N``; LabelError naming ``where`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise LabelError(f"{where}: force {value!r} is not a number ({_EXPECTED})")
    v = float(value)
    if not math.isfinite(v):
        raise LabelError(f"{where}: force {v} is not finite ({_EXPECTED})")
    if v < 0.0:
        raise LabelError(f"{where}: force {v:g} N is negative ({_EXPECTED}; tare the scale)")
    if v > MAX_FORCE_N:
        raise LabelError(f"{where}: force {v:g} N is above the physical bound {MAX_FORCE_N:g} N "
                         f"(wrong unit, e.g. grams written as newtons?)")
    return v


def parse_force_text(data: bytes, where: str) -> float:
    """The force in N held by the bytes of a label file; LabelError naming ``where`` otherwise."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise LabelError(f"{where}: not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start}); "
                         f"{_EXPECTED}") from None
    if "\x00" in text:
        raise LabelError(f"{where}: holds NUL bytes (a binary file?); {_EXPECTED}")
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if not lines:
        raise LabelError(f"{where}: empty; {_EXPECTED}")
    first = lines[0]
    if _DECIMAL_COMMA.match(first):
        raise LabelError(f"{where}: first line {first[:40]!r} has a decimal comma; write the force with a decimal "
                         f"point (e.g. 1.08); {_EXPECTED}")
    fields = [f for f in re.split(r"\s*[,;]\s*|\s+", first) if f]
    if not fields:  # separators only, e.g. "," or " ; "
        raise LabelError(f"{where}: first line {first[:40]!r} holds no number; {_EXPECTED}")
    token = fields[0]
    if not _NUMBER.fullmatch(token):
        if token.lower().lstrip("+-") in ("nan", "inf", "infinity"):
            raise LabelError(f"{where}: force {token!r} is not finite; {_EXPECTED}")
        m = _NUMBER.match(token)
        if m is not None and _UNIT.fullmatch(token[m.end():]):
            raise LabelError(f"{where}: first line {first[:40]!r} has a unit ({token[m.end():]!r}); write the force "
                             f"in newtons as a number alone (e.g. {m.group(0)}); {_EXPECTED}")
        raise LabelError(f"{where}: first line {first[:40]!r} is not a number; {_EXPECTED}")
    for extra in fields[1:]:
        if not _NUMBER.fullmatch(extra):
            what = "a unit" if _UNIT.fullmatch(extra) else "text"
            raise LabelError(f"{where}: first line {first[:40]!r} holds {what} ({extra[:12]!r}) after the force; "
                             f"write the force in newtons as a number alone (further columns: numbers only); "
                             f"{_EXPECTED}")
    return check_force(float(token), where)


#: A labelled set whose median force is above this (N) looks like another unit (warning).
UNIT_WARN_MEDIAN_N = 30.0


def unit_problem(forces, where: str) -> str | None:
    """Why the labels of a set look like another unit than newtons, or None.

    Parameters
    ----------
    forces : the set's forces, N (array-like of floats, each already valid).
    where : the set (a folder), for the message.

    Returns
    -------
    str or None : a warning naming the likely cause: a median above ``UNIT_WARN_MEDIAN_N``
    (a DIGIT or GelSight gel saturates near 15-25 N; the paper's range is 0-20 N, the largest
    real grasp in the shared data 44.5 N: ten times too large, e.g. decinewtons or a scale
    factor), or every force below 1 N while some are above 0 (kilograms-force or 1/10 N?).
    """
    vals = [float(f) for f in forces]
    if not vals:
        return None
    vals.sort()
    med = vals[len(vals) // 2]
    lo, hi = vals[0], vals[-1]
    if med > UNIT_WARN_MEDIAN_N:
        return (f"{where}: the labels span {lo:g} to {hi:g} N (median {med:g} N), above what a DIGIT or GelSight gel "
                f"measures (the paper's 0-20 N): are they in another unit or scaled (e.g. x10)? Labels must be the "
                "normal force in newtons")
    if 0.0 < hi < 1.0:
        return (f"{where}: every label is below 1 N ({lo:g} to {hi:g} N): are they in kilograms-force or scaled "
                "(e.g. /10)? Labels must be the normal force in newtons (1 kgf = 9.81 N)")
    return None


def read_force_file(path: str | Path) -> float:
    """First line of ``force_N.txt`` as newtons; LabelError naming the file otherwise.

    Parameters
    ----------
    path : label file.

    Returns
    -------
    float : the normal force in N, finite, ``0 <= F <= MAX_FORCE_N``.
    """
    from ..files.guard import special_file_kind

    p = Path(path)
    if (kind := special_file_kind(p)) is not None:  # reading a FIFO would block until someone writes to it
        raise LabelError(f"{p}: is a {kind}, not a regular file; {_EXPECTED}")
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise LabelError(f"{p}: force file missing; {_EXPECTED}") from None
    except OSError as exc:
        raise LabelError(f"{p}: cannot read ({exc.strerror or exc}); {_EXPECTED}") from None
    return parse_force_text(data, str(p))


def parse_meta_lines(data: bytes, where: str) -> dict[int, dict]:
    """Records of a ``meta.jsonl`` by sample id (a later line with the same id wins).

    Every non-blank line must be a JSON object with a non-negative integer ``"id"``;
    LabelError naming ``where`` and the line number otherwise (a truncated last line
    says how to repair it).
    """
    lines = data.split(b"\n")
    complete = data.endswith(b"\n")
    out: dict[int, dict] = {}
    for k, raw in enumerate(lines, start=1):
        if not raw.strip():
            continue
        last = k == len(lines) and not complete
        hint = (" (the last line is cut short, e.g. by a power cut: `tactile-force record --repair "
                f"{Path(where).parent}` drops it)") if last else ""
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise LabelError(f"{where} line {k}: not UTF-8 text (byte 0x{raw[exc.start]:02x}); "
                             f"expected one JSON object per line{hint}") from None
        try:
            rec = json.loads(text)
        except json.JSONDecodeError as exc:
            raise LabelError(f"{where} line {k}: not valid JSON ({exc.msg} at column {exc.colno}); "
                             f"expected one JSON object per line{hint}") from None
        except (ValueError, RecursionError):  # e.g. nesting too deep for the parser
            raise LabelError(f"{where} line {k}: not a JSON object this reader can parse; "
                             f"expected one JSON object per line{hint}") from None
        if not isinstance(rec, dict):
            raise LabelError(f"{where} line {k}: a JSON {type(rec).__name__}; expected an object with \"id\"")
        n = rec.get("id")
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise LabelError(f"{where} line {k}: \"id\" is {n!r}; expected the sample number N >= 0")
        out[n] = rec
    return out


def read_meta(path: str | Path) -> dict[int, dict]:
    """``meta.jsonl`` records by sample id; {} when the file is absent. See :func:`parse_meta_lines`."""
    from ..files.guard import special_file_kind

    p = Path(path)
    if (kind := special_file_kind(p)) is not None:
        raise LabelError(f"{p}: is a {kind}, not a regular file; expected one JSON object per line")
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        return {}
    except OSError as exc:
        raise LabelError(f"{p}: cannot read ({exc.strerror or exc})") from None
    return parse_meta_lines(data, str(p))


def complete_meta_prefix(data: bytes, keep_ids: set[int] | None = None) -> int:
    """Length in bytes of the part of a ``meta.jsonl`` to keep after a crash.

    Trailing lines are dropped while they are cut short (no newline), not a JSON object
    with an integer id, or (when ``keep_ids`` is given) name a sample not in ``keep_ids``
    (a frame whose label never landed). Complete lines before the first kept one stay,
    so truncating the file to this length never loses a complete sample's record.
    """
    end = len(data) if data.endswith(b"\n") else data.rfind(b"\n") + 1
    while end > 0:
        start = data.rfind(b"\n", 0, end - 1) + 1
        line = data[start:end].strip()
        if line:
            try:
                rec = json.loads(line.decode("utf-8"))
                n = rec.get("id") if isinstance(rec, dict) else None
                ok = isinstance(n, int) and not isinstance(n, bool) and (keep_ids is None or n in keep_ids)
            except (ValueError, RecursionError):
                ok = False
            if ok:
                return end
        end = start
    return 0
