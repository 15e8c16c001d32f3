"""Who measured what, where: the machine, its load while measuring, the command and the commit
every page states (:func:`header`); :class:`CpuWindow` watches the machine over a measurement.

Values that cannot be read on this host are None (never NaN), so the records go into
``report.json`` as they are (:mod:`tactile_force.edge.typed_json`)."""

from __future__ import annotations

import os
import platform
import shlex
import subprocess
import sys
import time
from dataclasses import dataclass


@dataclass(frozen=True)
class Machine:
    """The host: CPU model, logical cores, RAM (GiB; None when unknown), OS, Python and the
    versions of the runtimes measured, and its background load when the measurement started."""

    cpu: str
    cores: int
    ram_gib: float | None
    os: str
    python: str
    versions: str
    background_load: str

    def line(self) -> str:
        ram = "?" if self.ram_gib is None else f"{self.ram_gib:.0f}"
        return (f"{self.cpu}, {self.cores} logical cores, {ram} GiB RAM, {self.os}, "
                f"Python {self.python}; {self.versions}")


def _cpu_model() -> str:
    from tactile_force.edge.report.host import cpu_model

    return cpu_model()


def _ram_gib() -> float | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) / 2**20
    except OSError:
        pass
    return None


def _versions() -> str:
    import cv2
    import numpy as np
    import onnxruntime as ort

    parts = [f"onnxruntime {ort.__version__}", f"OpenCV {cv2.__version__}", f"numpy {np.__version__}"]
    if sys.modules.get("torch") is not None:
        parts.append(f"torch {sys.modules['torch'].__version__}")
    else:
        try:
            from importlib.metadata import version

            parts.append(f"torch {version('torch')}")
        except Exception:  # noqa: BLE001 - torch is optional here
            parts.append("torch not installed")
    return ", ".join(parts)


def background_load() -> str:
    """Load average and whether the reference training job was running (it competes for the cores)."""
    try:
        load = os.getloadavg()
        la = f"load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}"
    except OSError:
        la = "load average unknown"
    try:
        out = subprocess.run(["pgrep", "-f", "benchmarks.reference"], capture_output=True, text=True, timeout=5)
        pids = [p for p in out.stdout.split() if p.strip() and int(p) != os.getpid()]
        train = "reference training RUNNING (timings pessimistic)" if pids else "no reference training running"
    except (OSError, subprocess.SubprocessError, ValueError):
        train = "training status unknown"
    mhz = cpu_mhz()
    return f"{la}; CPU clock {'unknown' if mhz is None else f'{mhz:.0f} MHz'}; {train}"


def describe_machine() -> Machine:
    """This host, now."""
    return Machine(cpu=_cpu_model(), cores=os.cpu_count() or 1, ram_gib=_ram_gib(),
                   os=f"{platform.system()} {platform.release()}", python=platform.python_version(),
                   versions=_versions(), background_load=background_load())


def command_line(argv: list[str] | None = None) -> str:
    """The command that made a table, as the user would type it."""
    args = sys.argv[1:] if argv is None else argv
    return "python -m benchmarks " + " ".join(shlex.quote(a) for a in args)


def header(title: str, command: str, machine: Machine, notes: str = "") -> str:
    """Markdown header every docs/benchmarks page starts with: title, the command, the commit
    of the code that measured (:func:`benchmarks.harness.paths.source_commit`), the machine
    and its load, then ``notes``."""
    from .paths import source_commit

    out = [f"# {title}", "", f"Command: `{command}`", "", f"Commit: {source_commit()}", "",
           f"Machine: {machine.line()}.", f"While measuring: {machine.background_load}.", ""]
    if notes:
        out += [notes, ""]
    return "\n".join(out) + "\n"


# ----------------------------------------------------------------------------- busy or not

#: Share of the machine's CPU time (all cores) other processes may use during a measurement
#: before the machine counts as busy: on an idle host it stays near 0; at 12 % (a quarter of
#: one core of two) the compact model's p99 already doubled here.
BUSY_SHARE = 0.05


def cpu_mhz() -> float | None:
    """Mean current clock of the cores (MHz) from /proc/cpuinfo; None when unknown."""
    try:
        with open("/proc/cpuinfo") as f:
            mhz = [float(line.split(":", 1)[1]) for line in f if line.startswith("cpu MHz")]
    except (OSError, ValueError):
        return None
    return sum(mhz) / len(mhz) if mhz else None


def _cpu_jiffies() -> tuple[int, int] | None:
    """(busy, total) jiffies of all cores from /proc/stat, or None."""
    try:
        with open("/proc/stat") as f:
            v = [int(x) for x in f.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    idle = v[3] + (v[4] if len(v) > 4 else 0)  # idle + iowait
    return sum(v[:8]) - idle, sum(v[:8])


def _own_cpu_s() -> float:
    t = os.times()
    return t.user + t.system


@dataclass(frozen=True)
class MachineState:
    """What the machine did while something was measured: load average before / after
    (1 min), mean CPU clock (MHz) before / after, the share of all cores' time that OTHER
    processes used meanwhile (None: unknown), seconds, and busy (that share exceeded
    ``BUSY_SHARE``)."""

    load_before: float | None
    load_after: float | None
    mhz_before: float | None
    mhz_after: float | None
    others_share: float | None
    seconds: float
    busy: bool

    def line(self) -> str:
        def g(v: float | None, fmt: str) -> str:
            return "?" if v is None else format(v, fmt)

        share = "unknown" if self.others_share is None else f"{100 * self.others_share:.0f} %"
        return (f"load average (1 min) {g(self.load_before, '.2f')} -> {g(self.load_after, '.2f')}, CPU "
                f"{g(self.mhz_before, '.0f')} -> {g(self.mhz_after, '.0f')} MHz, other processes used {share} of "
                f"the cores over {self.seconds:.0f} s -> {'BUSY' if self.busy else 'quiet'}")


class CpuWindow:
    """Watch the machine over a measurement: ``w = CpuWindow(); ...; state = w.stop()``."""

    def __init__(self, busy_share: float = BUSY_SHARE) -> None:
        self.busy_share = busy_share
        self._load = _load1()
        self._mhz = cpu_mhz()
        self._jiffies = _cpu_jiffies()
        self._own = _own_cpu_s()
        self._t = time.monotonic()

    def stop(self) -> MachineState:
        seconds = time.monotonic() - self._t
        j1, own = _cpu_jiffies(), _own_cpu_s() - self._own
        share: float | None = None
        if self._jiffies is not None and j1 is not None and j1[1] > self._jiffies[1]:
            hz = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
            busy = (j1[0] - self._jiffies[0]) / hz
            total = (j1[1] - self._jiffies[1]) / hz
            share = max(0.0, (busy - own) / total)
        return MachineState(self._load, _load1(), self._mhz, cpu_mhz(), share, seconds,
                            share is not None and share > self.busy_share)


def _load1() -> float | None:
    try:
        return os.getloadavg()[0]
    except OSError:
        return None
