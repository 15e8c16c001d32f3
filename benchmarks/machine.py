"""Who measured what, where: the machine description and command line every table states."""

from __future__ import annotations

import os
import platform
import shlex
import subprocess
import sys
from dataclasses import dataclass


@dataclass(frozen=True)
class Machine:
    """CPU model, logical cores, RAM (GiB), OS and the versions of the runtimes measured."""

    cpu: str
    cores: int
    ram_gib: float
    os: str
    python: str
    versions: str
    background_load: str

    def line(self) -> str:
        return (f"{self.cpu}, {self.cores} logical cores, {self.ram_gib:.0f} GiB RAM, {self.os}, "
                f"Python {self.python}; {self.versions}")


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _ram_gib() -> float:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) / 2**20
    except OSError:
        pass
    return float("nan")


def _versions() -> str:
    import cv2
    import numpy as np
    import onnxruntime as ort

    parts = [f"onnxruntime {ort.__version__}", f"OpenCV {cv2.__version__}", f"numpy {np.__version__}"]
    if "torch" in sys.modules:
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
    return f"{la}; {train}"


def describe_machine() -> Machine:
    return Machine(cpu=_cpu_model(), cores=os.cpu_count() or 1, ram_gib=_ram_gib(),
                   os=f"{platform.system()} {platform.release()}", python=platform.python_version(),
                   versions=_versions(), background_load=background_load())


def command_line(argv: list[str] | None = None) -> str:
    """The command that made a table, as the user would type it."""
    args = sys.argv[1:] if argv is None else argv
    return "python -m benchmarks " + " ".join(shlex.quote(a) for a in args)


def header(title: str, command: str, machine: Machine, notes: str = "") -> str:
    """Markdown header every docs/benchmarks page starts with."""
    out = [f"# {title}", "", f"Command: `{command}`", "", f"Machine: {machine.line()}.",
           f"While measuring: {machine.background_load}.", ""]
    if notes:
        out += [notes, ""]
    return "\n".join(out) + "\n"
