"""Instructions counted by valgrind's callgrind: run a command under it, read the profile it
writes, and group the self cost (instructions executed, ``Ir``) by where it ran: the object
file (onnxruntime, OpenCV, numpy, OpenBLAS, the interpreter, ...) and, inside the C library,
memset / memcpy apart from the rest.

Instruction counts do not depend on the machine's load or clock: the figure that moves only
when the code does. Callgrind runs what it instruments about 50x slower than natively
(:func:`run_segments`: only the segments the program marks).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

#: Where an instruction ran, in the order the pages list them: group -> regular expression
#: on the object file's name (the first that matches wins; "libc memset/memcpy" is decided
#: by the function's name inside the C library, see :func:`group_of`).
GROUPS: tuple[tuple[str, str], ...] = (
    ("onnxruntime", r"onnxruntime"),
    ("OpenCV", r"(libopencv|cv2|/opencv)"),
    ("OpenBLAS", r"openblas"),
    ("numpy", r"(numpy|_multiarray|_umath)"),
    ("scipy", r"scipy"),
    ("libm", r"libm[.-]"),
    ("libc memset/memcpy", r"^$"),  # decided by the function name (group_of)
    ("libc other", r"libc[.-]"),
    ("interpreter", r"(python3|libpython)"),
)
OTHER = "other"
GROUP_NAMES: tuple[str, ...] = tuple(g for g, _ in GROUPS) + (OTHER,)
_GROUP_RE = [(g, re.compile(p)) for g, p in GROUPS if p != "^$"]
_MEM_RE = re.compile(r"(memset|memcpy|memmove|mempcpy|bzero)")


class ValgrindMissing(RuntimeError):
    """valgrind (with its callgrind tool) is not installed on this host."""


def valgrind() -> str | None:
    """The valgrind executable, or None when it is not installed."""
    return shutil.which("valgrind")


def version() -> str:
    """valgrind's version line (e.g. 'valgrind-3.19.0'), or '' without valgrind."""
    vg = valgrind()
    if vg is None:
        return ""
    proc = subprocess.run([vg, "--version"], capture_output=True, text=True, timeout=60)
    return proc.stdout.strip()


def group_of(obj: str, fn: str) -> str:
    """The group of an instruction that ran in function ``fn`` of object file ``obj``."""
    base = os.path.basename(obj)
    if re.match(r"libc[.-]", base) and _MEM_RE.search(fn):
        return "libc memset/memcpy"
    for g, rx in _GROUP_RE:
        if rx.search(base) or (g in ("onnxruntime", "OpenCV", "numpy", "scipy") and rx.search(obj)):
            return g
    return OTHER


@dataclass
class Profile:
    """One callgrind run: total instructions and the self cost per (object file, function)."""

    total: int
    by_function: dict[tuple[str, str], int] = field(default_factory=dict)

    def by_group(self) -> dict[str, int]:
        """Self cost per group of :data:`GROUP_NAMES` (every group present, 0 when none)."""
        out = dict.fromkeys(GROUP_NAMES, 0)
        for (obj, fn), ir in self.by_function.items():
            out[group_of(obj, fn)] += ir
        return out


def parse(path: str | os.PathLike) -> Profile:
    """Read a callgrind profile (``--compress-strings`` on or off) into a :class:`Profile`:
    self cost lines only (a call's inclusive cost, the line after ``calls=``, is skipped)."""
    names: dict[str, dict[str, str]] = {"ob": {}, "fn": {}}
    by: dict[tuple[str, str], int] = {}
    obj, fn = "", ""
    skip_next = False
    total = 0
    events_ir = 0  # column of Ir among the events
    npos = 1  # position columns before the events

    def name(kind: str, value: str) -> str:
        m = re.match(r"\((\d+)\)\s*(.*)", value)
        if not m:
            return value
        key, text = m.group(1), m.group(2)
        if text:
            names[kind][key] = text
            return text
        return names[kind].get(key, key)

    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if not line or line == "\n":
                continue
            c = line[0]
            if c.isdigit() or c in "+-*":
                if skip_next:
                    skip_next = False
                    continue
                parts = line.split()
                if len(parts) > npos + events_ir:
                    ir = int(parts[npos + events_ir])
                    by[(obj, fn)] = by.get((obj, fn), 0) + ir
                continue
            if line.startswith("ob="):
                obj = name("ob", line[3:].strip())
            elif line.startswith("fn="):
                fn = name("fn", line[3:].strip())
            elif line.startswith("cob="):
                name("ob", line[4:].strip())
            elif line.startswith("cfn="):
                name("fn", line[4:].strip())
            elif line.startswith("calls="):
                skip_next = True
            elif line.startswith("positions:"):
                npos = len(line.split(":", 1)[1].split())
            elif line.startswith("events:"):
                ev = line.split(":", 1)[1].split()
                events_ir = ev.index("Ir") if "Ir" in ev else 0
            elif line.startswith("summary:") or line.startswith("totals:"):
                total = int(line.split(":", 1)[1].split()[events_ir])
    if not total:
        total = sum(by.values())
    return Profile(total, by)


def run_segments(cmd: Sequence[str], out_file: Path, env: Mapping[str, str] | None = None,
                 timeout_s: float = 900) -> dict[str, Profile]:
    """Run ``cmd`` under callgrind (instructions only, no cache simulation) with instrumentation
    and counting off until the program turns them on (its
    :class:`~.client_requests.Segment` blocks); returns each segment's profile of the main
    thread (``out_file``.K-01) by the segment's name. Raises :class:`ValgrindMissing` without
    valgrind, ``subprocess.CalledProcessError`` when the command fails and ``RuntimeError`` when
    it wrote no segment."""
    vg = valgrind()
    if vg is None:
        raise ValgrindMissing("valgrind is not installed on this host: instruction counts need valgrind's callgrind "
                              "(e.g. apt-get install valgrind)")
    # The main thread only (``-01``): a helper thread that spins while it waits (a library's pool)
    # counts as long as the run lasts, which the machine's load decides, not the code.
    full = [vg, "--tool=callgrind", f"--callgrind-out-file={out_file}", "--compress-strings=no",
            "--compress-pos=no", "--dump-line=no", "--separate-threads=yes", "--instr-atstart=no",
            "--collect-atstart=no", *cmd]
    proc = subprocess.run(full, env=None if env is None else dict(env), capture_output=True, text=True,
                          timeout=timeout_s)
    if proc.returncode != 0:
        raise subprocess.CalledProcessError(proc.returncode, full, proc.stdout, proc.stderr)
    out: dict[str, Profile] = {}
    for part in sorted(out_file.parent.glob(f"{out_file.name}.*-01")):
        with open(part, encoding="utf-8", errors="replace") as f:
            trigger = next((line for line in f if line.startswith("desc: Trigger:")), "")
        m = re.search(r"Client Request: (\w+)", trigger)
        if m:
            out[m.group(1)] = parse(part)
    if not out:
        raise RuntimeError(f"{' '.join(cmd)} counted no segment under callgrind (no dump in {out_file.parent})")
    return out


def unavailable(what: str) -> str:
    """Why ``what`` (a page counted under callgrind with client requests) cannot be counted on this host,
    one line; '' when it can."""
    from .client_requests import SUPPORTED

    if valgrind() is None:
        return (f"{what}: valgrind is not installed on this host; the counts need valgrind's callgrind (e.g. apt-get "
                "install valgrind). Nothing counted.")
    if not SUPPORTED:
        import platform

        return (f"{what}: callgrind's client requests, which count each stage apart, are made here on x86-64 only, "
                f"not {platform.machine()}. Nothing counted.")
    return ""
