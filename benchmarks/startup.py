"""Start-up: process start -> the first reading, cold and warm, per install, beside the import floor.

    python -m benchmarks startup --out docs/benchmarks                                # this interpreter
    python -m benchmarks startup --python /opt/robot/bin/python --python .venv/bin/python --out DIR

Each figure is the wall time of a new process (interpreter start included), the median of
``--runs``: the import floor (``import numpy, cv2, onnxruntime``, what any reading needs), and a
process that builds a ``ForceRuntime`` on a shipped bundle with a ``VirtualDigitSource`` and takes
the first reading ``step()`` returns (then exits at once, no clean-up timed). Per interpreter (an
install): the robot-side path (``TACTILE_FORCE_KERNELS=off``, numba never imported: what an install
without the ``fast`` extra runs), and where numba is installed the default ``auto`` mode with an
empty cache (a new container) and with the kernels compiled ahead by ``tactile-force kernels``, whose
own time is measured once; and ``tactile-force demo --grasps 1`` with an empty cache, then again.
Every cold run gets a new empty ``XDG_CACHE_HOME``. The size of each install's site-packages too.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from .harness.machine import command_line, describe_machine, header
from .harness.stats import markdown_table

PAGE, JSON = "startup.md", "startup.json"

#: the floor: what every reading needs, imported and nothing else
FLOOR = "import numpy, cv2, onnxruntime, os; os._exit(0)"
#: the first reading of a runtime on bundle {bundle!r}; exits at once (no clean-up timed)
FIRST = ("import os\nfrom tactile_force.edge import ContactGate, ForceRuntime, OnnxForceModel, RuntimeOptions, Sensor, "
         "VirtualDigitSource, shipped_bundles\n"
         "rt = ForceRuntime([Sensor('s', VirtualDigitSource(seed=0, n_grasps=1), ContactGate())], "
         "OnnxForceModel(shipped_bundles()[{bundle!r}], threads=1), RuntimeOptions(deadline_ms=16.7))\n"
         "assert rt.step()\nos._exit(0)\n")
#: what an interpreter has: numba importable, its site-packages folder
PROBE = ("import importlib.util, json, sysconfig; print(json.dumps({'numba': importlib.util.find_spec('numba') "
         "is not None, 'site': sysconfig.get_paths()['purelib']}))")


@dataclass
class InstallRow:
    """Start-up figures of one interpreter (seconds, medians; None: not measured there)."""

    python: str
    site_mb: float
    numba: bool
    floor_s: float
    off_s: dict[str, float] = field(default_factory=dict)  # bundle -> robot-side path
    auto_cold_s: dict[str, float] = field(default_factory=dict)  # bundle -> auto, empty cache
    auto_warm_s: dict[str, float] = field(default_factory=dict)  # bundle -> auto, kernels compiled ahead
    compile_s: float | None = None  # tactile-force kernels, empty cache
    demo_first_s: float | None = None
    demo_second_s: float | None = None


def _du_mb(path: str) -> float:
    total = 0
    for root, _, files in os.walk(path):
        for f in files:
            p = os.path.join(root, f)
            if not os.path.islink(p):
                total += os.path.getsize(p)
    return total / 1e6


def _timed(cmd: list[str], env: dict[str, str], cwd: str) -> float:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=600)
    dt = time.perf_counter() - t0
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[:3])}...: exit {p.returncode}: {p.stderr.strip()[-400:]}")
    return dt


def _median(runs: int, make: Callable[[], float]) -> float:
    return statistics.median(make() for _ in range(runs))


def measure(python: str, runs: int, bundles: list[str], demo: bool) -> InstallRow:
    """Every figure of one interpreter (see the module docstring)."""
    probe = json.loads(subprocess.run([python, "-c", PROBE], capture_output=True, text=True, check=True).stdout)
    base = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "TACTILE_FORCE_KERNELS")}
    with tempfile.TemporaryDirectory() as tmp:
        cwd = tmp  # not the clone: the install's own package is imported

        def fresh(mode: str) -> dict[str, str]:
            return {**base, "XDG_CACHE_HOME": tempfile.mkdtemp(dir=tmp), "TACTILE_FORCE_KERNELS": mode}

        row = InstallRow(python, round(_du_mb(probe["site"]), 1), probe["numba"],
                         _median(runs, lambda: _timed([python, "-c", FLOOR], base, cwd)))
        def first(bundle: str, env: dict[str, str] | None = None, mode: str = "off") -> float:
            return _median(runs, lambda: _timed([python, "-c", FIRST.format(bundle=bundle)],
                                                env if env is not None else fresh(mode), cwd))

        for b in bundles:
            row.off_s[b] = first(b)
        if probe["numba"]:
            warm = fresh("auto")
            tf = str(Path(python).with_name("tactile-force"))
            row.compile_s = _timed([tf, "kernels"], warm, cwd)
            for b in bundles:
                row.auto_cold_s[b] = first(b, mode="auto")
                row.auto_warm_s[b] = first(b, warm)
        if demo:
            env = fresh("auto")
            tf = str(Path(python).with_name("tactile-force"))
            row.demo_first_s = _timed([tf, "demo", "--grasps", "1", "--out", os.path.join(tmp, "d1")], env, cwd)
            row.demo_second_s = _timed([tf, "demo", "--grasps", "1", "--out", os.path.join(tmp, "d2")], env, cwd)
    return row


def _f(v: float | None) -> str:
    return "-" if v is None else f"{v:.2f}"


def table(rows: list[InstallRow], bundles: list[str]) -> str:
    """One row per install and bundle: the floor, the first reading per path and its excess over the floor."""
    out = []
    for r in rows:
        for b in bundles:
            warm = r.auto_warm_s.get(b)
            off = r.off_s[b]
            install = "with the fast extra" if r.numba else "robot-side (no extra)"
            out.append([r.python, install, f"{r.site_mb:.0f}", b, _f(r.floor_s), _f(off), f"+{off - r.floor_s:.2f}",
                        _f(r.auto_cold_s.get(b)), _f(warm), "-" if warm is None else f"+{warm - r.floor_s:.2f}"])
    return markdown_table(["interpreter", "install", "site-packages MB", "bundle", "import floor s",
                           "first reading, robot-side path s", "over the floor",
                           "fast extra, empty cache s", "fast extra, compiled ahead s", "over the floor"], out)


def run(args, argv) -> int:
    """``python -m benchmarks startup``: measure each ``--python``, write startup.md and startup.json."""
    pythons = args.python or [sys.executable]
    bundles = ["default", "d"]
    rows = []
    for py in pythons:
        print(f"startup: {py} ({args.runs} runs per figure) ...", flush=True)
        rows.append(measure(py, args.runs, bundles, demo=True))
    machine = describe_machine()
    command = command_line(argv)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    (out / JSON).write_text(json.dumps({"command": command, "machine": asdict(machine),
                                        "rows": [asdict(r) for r in rows]}, indent=1) + "\n")
    extra = [[r.python, _f(r.compile_s), _f(r.demo_first_s), _f(r.demo_second_s)] for r in rows]
    notes = (f"Median of {args.runs} new processes per figure; wall time from process start to the first "
             "reading `ForceRuntime.step()` returns (a `VirtualDigitSource`, one thread), the process exiting "
             "at once. 'Robot-side path': `TACTILE_FORCE_KERNELS=off`, numba never imported, what an install "
             "without the `fast` extra runs. 'Empty cache': a new `XDG_CACHE_HOME` per run (a new container); "
             "'compiled ahead': after `tactile-force kernels` (timed once below).\n\n"
             "Why the kernels are compiled ahead and not in the background while OpenCV serves: numba holds the "
             "interpreter lock while it compiles; a gate fed at 60 fps while a thread compiled its kernels (10 s) took "
             "p99 55-135 ms per second (max 150 ms) instead of 0.4-0.6 ms, and loading them from the cache in a "
             "thread still stalled the first second's readings up to 20 ms (AMD EPYC VM, measured when this "
             "mechanism was chosen, an investigation not kept as code). Loading them when the gate is made costs the "
             "start-up above.")
    text = header("Start-up: process start to the first reading", command, machine, notes) + "\n".join([
        table(rows, bundles), "",
        markdown_table(["interpreter", "tactile-force kernels (compile, empty cache) s",
                        "demo --grasps 1, empty cache s", "demo again s"], extra), ""])
    (out / PAGE).write_text(text)
    print(f"wrote {out / PAGE}, {out / JSON}")
    return 0
