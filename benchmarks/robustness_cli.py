"""Robustness categories of the command line's own promises: a signal at the CLI's earliest
moments, numeric arguments at their extremes, the old module paths and names, the bench's
statistics floor and its warm-up misses.

Each entry of :data:`CATEGORIES` is ``(key, name, build)``; ``build(folder, examples)``
returns ``(cases, note)`` with ``cases`` ``(what, probe)`` pairs run by
:func:`benchmarks.robustness_inputs.run_cases`. The tests run the same probes:
tests/robustness/test_cli_signals_early.py, tests/robustness/test_numeric_arguments.py,
tests/edge/test_moved.py, tests/benchmarks/test_bench_statistics.py.
"""

from __future__ import annotations

import functools
import math
import signal
import subprocess
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path

from .harness.cases import Outcome, Verdict, run_cli
from .robustness_table import fill, rows, values

Cases = tuple[list[tuple[str, Callable[[], Verdict]]], str]

# =============================================================================== signals at start
#: seconds after the package starts loading at which the early signals are sent
EARLY_DELAYS = tuple(values("early_delays_s"))


def cli_argv(*args: str) -> list[str]:
    """``python -m tactile_force.edge.cli ARGS`` (the CLI as the console script starts it)."""
    return [sys.executable, "-m", "tactile_force.edge.cli", *args]


def _package_loading(pid: int) -> bool:
    """Whether process ``pid`` has started loading the package (numpy's core library is
    mapped: the package's first import needs it; Linux /proc)."""
    try:
        return "_multiarray_umath" in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return False


def signal_at_start(args: list[str], sig: int, delay_s: float, timeout_s: float = 120.0
                    ) -> tuple[int | None, str]:
    """Start ``tactile-force ARGS``, wait until it starts loading the package, then ``delay_s``
    more, send ``sig``; (exit code, stderr). The code is None when the process ended before
    the signal could be sent."""
    proc = subprocess.Popen(cli_argv(*args), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + timeout_s
        while not _package_loading(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.001)
        if delay_s:
            time.sleep(delay_s)
        if proc.poll() is not None:
            return None, proc.communicate()[1]
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=timeout_s)
        return proc.returncode, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def early_signal_verdict(args: list[str], sig: int, delay_s: float) -> Verdict:
    """Exit 128 + the signal, one line, no traceback, whatever the moment."""
    if not Path("/proc/self/maps").exists():
        return Verdict(Outcome.ACCEPTED, "not run: needs Linux /proc to see the package start loading")
    rc, err = signal_at_start(args, sig, delay_s)
    name = signal.Signals(sig).name
    if rc is None:
        return Verdict(Outcome.TRACEBACK, f"ended before {name} at +{delay_s:g} s: {err[-200:]}")
    if "Traceback" in err or rc != 128 + int(sig):
        return Verdict(Outcome.TRACEBACK, f"{name} at +{delay_s:g} s: exit {rc}: {err.strip()[-240:]}")
    return Verdict(Outcome.CLEAR, f"{name} at +{delay_s:g} s: exit {rc}: {err.strip()[-120:]}")


#: verbs that run well past the early moments (no data needed)
def early_signal_verbs(folder: Path) -> list[tuple[str, list[str]]]:
    return [("bench", ["bench", "--out", str(folder / "bench"), "--frames", "200"]),
            ("run", ["run", "--source", "virtual", "--max-frames", "100000"])]


def early_signal_cases(folder: Path, examples: int) -> Cases:
    cases: list[tuple[str, Callable[[], Verdict]]] = []
    for verb, args in early_signal_verbs(folder):
        for delay in EARLY_DELAYS:
            cases.append((f"{verb}, SIGINT", lambda a=args, d=delay: early_signal_verdict(a, signal.SIGINT, d)))
        for delay in (0.0, 0.1):
            cases.append((f"{verb}, SIGTERM", lambda a=args, d=delay: early_signal_verdict(a, signal.SIGTERM, d)))
    return cases, "delays counted from the moment the process starts loading the package"


CATEGORIES: list[tuple[str, str, Callable[[Path, int], Cases]]] = [
    ("early_signals", "signals at the CLI's first moments (SIGINT 0-0.3 s, SIGTERM, into bench and run)",
     early_signal_cases),
]


# =============================================================================== numeric arguments
#: texts every numeric flag must refuse (or accept only inside its declared range)
EXTREME_TEXTS = tuple(values("extreme_texts"))


def numeric_flags() -> list[tuple[str, str, object]]:
    """(verb, flag, argparse action) of every numeric flag of every verb whose module imports
    here (a verb needing a missing extra is left out): a flag whose type is not ``str``,
    ``Path`` or a choice list and reads ``"1"`` as a number."""
    import argparse
    import importlib

    from tactile_force.edge.cli import COMMANDS

    out: list[tuple[str, str, object]] = []
    for verb, (module_name, configure, _main, _help) in COMMANDS.items():
        try:
            module = importlib.import_module(module_name)
        except ImportError:
            continue
        parser = argparse.ArgumentParser(prog=f"tactile-force {verb}")
        getattr(module, configure)(parser)
        for action in parser._actions:  # argparse keeps its options here
            flags = [f for f in action.option_strings if f.startswith("--")]
            if not flags or action.type in (None, str, Path) or action.choices is not None:
                continue
            try:
                v = action.type("1")
            except Exception:  # noqa: BLE001 - a non-numeric type refusing "1" (or a numeric one with a floor above 1)
                v = 1
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                out.append((verb, flags[0], action))
    return out


def probe_numeric_flag(verb: str, flag: str, action: object, text: str) -> Verdict:
    """``tactile-force VERB FLAG TEXT`` as the parser reads it: refused (exit 2 naming the flag)
    or accepted inside the flag's declared finite range; never a traceback."""
    import argparse

    chk = getattr(action.type, "check", None)  # type: ignore[attr-defined]
    if chk is None:
        return Verdict(Outcome.TRACEBACK, f"{verb} {flag}: no declared range (a bare int/float type)")
    lo = chk.gt if chk.gt is not None else chk.ge
    hi = chk.lt if chk.lt is not None else chk.le
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return Verdict(Outcome.TRACEBACK, f"{verb} {flag}: range open at an end ({chk.range_text()})")
    try:
        v = action.type(text)  # type: ignore[attr-defined]
    except (argparse.ArgumentTypeError, ValueError, TypeError):
        rc, _out, err = _parse_only(verb, [flag, text])
        if rc != 2 or flag not in err or "Traceback" in err:
            return Verdict(Outcome.TRACEBACK, f"{verb} {flag} {text!r}: exit {rc}: {err[-200:]}")
        return Verdict(Outcome.CLEAR, f"{verb} {flag} {text!r}: {err.strip()[-120:]}")
    except Exception as exc:  # noqa: BLE001 - classified
        return Verdict(Outcome.TRACEBACK, f"{verb} {flag} {text!r}: {type(exc).__name__}: {exc}"[:300])
    if not (isinstance(v, (int, float)) and math.isfinite(v) and chk.in_range(v)):
        return Verdict(Outcome.SILENT_WRONG, f"{verb} {flag} {text!r} accepted as {v!r} ({chk.range_text()})")
    return Verdict(Outcome.ACCEPTED, f"{verb} {flag} {text!r} -> {v!r}")


def _parse_only(verb: str, argv: list[str]) -> tuple[int, str, str]:
    """The verb's parser on ``argv`` only (no work): (exit code, stdout, stderr)."""
    import argparse
    import contextlib
    import importlib
    import io

    from tactile_force.edge.cli import COMMANDS

    module_name, configure, _main, _help = COMMANDS[verb]
    parser = argparse.ArgumentParser(prog=f"tactile-force {verb}")
    getattr(importlib.import_module(module_name), configure)(parser)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            parser.parse_known_args(argv)
            rc = 0
        except SystemExit as exc:
            rc = exc.code if isinstance(exc.code, int) else 2
    return rc, out.getvalue(), err.getvalue()


def numeric_flag_cases(folder: Path, examples: int) -> Cases:
    cases: list[tuple[str, Callable[[], Verdict]]] = []
    for verb, flag, action in numeric_flags():
        for text in EXTREME_TEXTS:
            cases.append((f"{verb} {flag}", lambda v=verb, f=flag, a=action, t=text: probe_numeric_flag(v, f, a, t)))
    return cases, ""


def _api_case(call: Callable[[], object], names: tuple[str, ...]) -> Verdict:
    from .harness.cases import refusal

    try:
        call()
    except Exception as exc:  # noqa: BLE001 - classified
        return refusal(exc, True, names=names)
    return Verdict(Outcome.SILENT_WRONG, "accepted")


def api_numeric_cases() -> list[tuple[str, Callable[[], object], tuple[str, ...]]]:
    """Public constructors and options records at their numeric extremes (robustness_cases.toml
    ``[[numeric_api]]``): (what, call, names the error must hold)."""
    import numpy as np
    import tactile_force.edge as edge

    out: list[tuple[str, Callable[[], object], tuple[str, ...]]] = []
    for row in rows("numeric_api"):
        kwargs = dict(row["kwargs"])
        for key in row.get("as_tuple", []):
            kwargs[key] = tuple(kwargs[key])
        for key in row.get("as_numpy_int", []):
            kwargs[key] = np.int64(kwargs[key])
        cls, args = getattr(edge, row["call"]), row.get("args", [])
        shown = ", ".join([*map(repr, args), *(f"{k}={v!r}" for k, v in kwargs.items())])
        out.append((f"{row['call']}({shown})", functools.partial(cls, *args, **kwargs),
                    tuple(f"{row['call']}.{k}" for k in kwargs)))
    return out


def cli_numeric_cases(folder: Path) -> list[tuple[list[str], str]]:
    """The reported CLI cases, run whole (robustness_cases.toml ``[[numeric_run]]``): (argv, the
    flag the message must name); exit 2."""
    return [(fill(row["argv"], {"folder": folder}), row["flag"]) for row in rows("numeric_run")]


def cli_numeric_verdict(argv: list[str], flag: str, folder: Path) -> Verdict:
    from .harness.cases import cli_verdict

    before = sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []
    v = cli_verdict(argv, {2}, True, (flag,))
    after = sorted(p.name for p in folder.iterdir()) if folder.is_dir() else []
    if v.ok and after != before:
        return Verdict(Outcome.SILENT_WRONG, f"{' '.join(argv)}: left {sorted(set(after) - set(before))}")
    return v


def numeric_api_cases(folder: Path, examples: int) -> Cases:
    cases: list[tuple[str, Callable[[], Verdict]]] = []
    for what, call, names in api_numeric_cases():
        cases.append((what, lambda c=call, n=names: _api_case(c, n)))
    for argv, flag in cli_numeric_cases(folder):
        cases.append((" ".join(argv[:1] + argv[1:3]), lambda a=argv, f=flag: cli_numeric_verdict(a, f, folder)))
    return cases, ""


CATEGORIES += [
    ("numeric_flags", "numeric flags of every verb at their extremes (1e-300, 1e300, nan, inf, -1, 10^30, ...)",
     numeric_flag_cases),
    ("numeric_api", "numeric arguments of the public constructors and options, and the reported CLI cases",
     numeric_api_cases),
]


# =============================================================================== old names
_TOPS = {"edge": "tactile_force.edge", "export": "tactile_force.export",
         "firmware_bridge": "tactile_force.firmware_bridge"}


def _module_of(path: str) -> str:
    top, rest = path.split("/", 1)
    name = _TOPS[top] + "." + rest[:-3].replace("/", ".")
    return name.removesuffix(".__init__")


def _public_names(source: str) -> set[str]:
    """The names a module's source makes public: its ``__all__``, else its top-level
    definitions and assignments not starting with ``_``."""
    import ast

    try:
        tree = ast.parse(source)
    except SyntaxError:
        return set()
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            for target in node.targets if isinstance(node, ast.Assign) else [node.target]:
                if isinstance(target, ast.Name) and target.id == "__all__":
                    try:
                        return {str(n) for n in ast.literal_eval(node.value)}  # type: ignore[arg-type]
                    except ValueError:
                        pass
                elif isinstance(target, ast.Name):
                    names.add(target.id)
    return {n for n in names if not n.startswith("_")}


def history_names(repo: Path) -> dict[str, set[str]]:
    """Every module of the package that ever existed (git history of ``repo``), with every
    public name any version of it had. Empty when ``repo`` has no git history."""
    log = subprocess.run(["git", "-C", str(repo), "log", "--format=C %H", "--name-status", "-M", "--", *_TOPS],
                         capture_output=True, text=True)
    if log.returncode != 0:
        return {}
    wanted: list[tuple[str, str]] = []  # (rev:path, module)
    commit = ""
    for line in log.stdout.splitlines():
        if line.startswith("C "):
            commit = line[2:]
            continue
        parts = line.split("\t")
        if len(parts) < 2:
            continue
        status, paths = parts[0], parts[1:]
        gone = status == "D" or status.startswith("R")
        path = paths[0] if gone else paths[-1]
        if path.endswith(".py") and not path.endswith("__main__.py"):
            wanted.append((f"{commit}^:{path}" if gone else f"{commit}:{path}", _module_of(path)))
    batch = subprocess.run(["git", "-C", str(repo), "cat-file", "--batch"],
                           input="".join(f"{w}\n" for w, _ in wanted).encode(), capture_output=True)
    out: dict[str, set[str]] = {}
    data = batch.stdout
    pos = 0
    for _, module in wanted:  # each answer: "<sha> blob <size>\n<bytes>\n", or "<rev> missing\n"
        header_end = data.index(b"\n", pos)
        header = data[pos:header_end].split()
        pos = header_end + 1
        if len(header) < 3 or header[1] != b"blob":
            continue
        size = int(header[2])
        body = data[pos:pos + size].decode("utf-8", "replace")
        pos += size + 1
        out.setdefault(module, set()).update(_public_names(body))
    return out


def old_name_verdict(module: str, name: str | None) -> Verdict:
    """``import module`` (``name`` None) or ``from module import name`` now: present, or a
    DeprecationWarning naming the new home, or an ImportError naming what replaced it."""
    import importlib

    from tactile_force.edge import _moved

    key = module.removeprefix("tactile_force.")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            mod = importlib.import_module(module)
            if name is not None:
                getattr(mod, name)
        except ImportError as exc:
            from tactile_force.edge.errors import MissingExtraError

            if isinstance(exc, MissingExtraError) or getattr(exc, "name", "") in ("mcap", "cyclonedds", "foxglove"):
                return Verdict(Outcome.ACCEPTED, f"{module}: needs an extra ({exc})")
            replaced = _moved.GONE_MODULES.get(key) or (_moved.GONE.get(key, {}).get(name or "") if name else None)
            if replaced and replaced in str(exc):
                return Verdict(Outcome.CLEAR, f"{module}.{name or ''}: {exc}"[:200])
            return Verdict(Outcome.TRACEBACK, f"{module} {name or ''}: {type(exc).__name__}: {exc}"[:300])
        except AttributeError as exc:
            return Verdict(Outcome.TRACEBACK, f"{module}.{name}: {exc}"[:300])
    said = [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]
    return Verdict(Outcome.ACCEPTED, f"{module}{'.' + name if name else ''}: {said[-1] if said else 'present'}"[:200])


def old_name_cases(folder: Path, examples: int) -> Cases:
    from .harness.paths import require_repo

    names = history_names(require_repo("the old-names category"))
    if not names:
        return [], "not run: no git history"
    cases: list[tuple[str, Callable[[], Verdict]]] = []
    for module in sorted(names):
        cases.append((module, lambda m=module: old_name_verdict(m, None)))
        for name in sorted(names[module]):
            cases.append((f"{module}.{name}", lambda m=module, n=name: old_name_verdict(m, n)))
    return cases, "every module path and public name in the git history"


CATEGORIES += [
    ("old_names", "old module paths and public names from the git history (import works, warns, or names the "
                  "replacement)", old_name_cases),
]


# =============================================================================== bench statistics
def bench_stats_verdict(folder: Path, fps: float, cadence_frames: int, frames: int) -> Verdict:
    """``bench --fps F --cadence-frames C --frames N``: the readings at the cadence and the
    missed frames add up to C (warm-up frames never count as missed), and the verdict is
    TOO_FEW_READINGS exactly when fewer than MIN_P99_READINGS readings were measured at the cadence."""
    from tactile_force.benchmarks.bench import REPORT_JSON, read_report
    from tactile_force.edge.scene import default_bundle_path

    from .harness.stats import MIN_P99_READINGS

    out = folder / f"bench_{fps:g}_{cadence_frames}_{frames}"
    argv = ["bench", "--bundle", str(default_bundle_path()), "--fps", f"{fps:g}", "--cadence-frames",
            str(cadence_frames), "--frames", str(frames), "--repeats", "1", "--budget-ms", "1000", "--out", str(out)]
    what = " ".join(argv[3:9])
    rc, stdout, stderr = run_cli(argv)
    if "Traceback" in stdout + stderr or rc not in (0, 1):
        return Verdict(Outcome.TRACEBACK, f"{what}: exit {rc}: {stderr[-200:]}")
    b = read_report(out / REPORT_JSON).bundles[0]
    if b.cadence is None:
        return Verdict(Outcome.SILENT_WRONG, f"{what}: no cadence record")
    n, missed = b.cadence.total_ms.n, b.cadence.missed
    if n + missed != cadence_frames:
        return Verdict(Outcome.SILENT_WRONG, f"{what}: n {n} + missed {missed} != {cadence_frames} (warm-up counted)")
    few = n < MIN_P99_READINGS
    if (b.verdict == "TOO_FEW_READINGS") != few:
        return Verdict(Outcome.SILENT_WRONG if not few else Outcome.VALID_REFUSED,
                       f"{what}: verdict {b.verdict} from {n} readings at the cadence")
    return Verdict(Outcome.CLEAR if few else Outcome.ACCEPTED, f"{what}: n {n}, missed {missed}, {b.verdict}")


def bench_stats_cases(folder: Path, examples: int) -> Cases:
    runs = [(10_000.0, 100, 5), (200.0, 120, 99), (200.0, 99, 100)]
    return [(f"bench --fps {f:g} --cadence-frames {c} --frames {n}",
             lambda f=f, c=c, n=n: bench_stats_verdict(folder, f, c, n)) for f, c, n in runs], ""


CATEGORIES += [
    ("bench_statistics", "bench statistics (warm-up frames never missed; too few readings: one rule at the cadence)",
     bench_stats_cases),
]
