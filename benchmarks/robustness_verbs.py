"""Every verb keeps the package's promises: cases for the robustness catalogue
(benchmarks/robustness.py) on the verbs that write result folders (``bench``, ``study``,
``synth``, ``demo``), their interruption, the statistics floor of a p99 verdict, labelled data
judged before any work, the Python API's argument types and the honest states (``bundle
verify`` claims, learning-time intervals, ``scene show`` answering as ``run``).

Each case is the user's command through the CLI in-process (a subprocess for signals) or a
call of the public API, classified like every other case of the catalogue: ``data lost`` when a
user's file or an input changed or vanished (or an earlier result was lost), ``silent wrong``
when a bad input was taken or a success exit (or a verdict) came from a partial or meaningless
result, ``traceback`` on an uncaught exception, a CLI traceback or a wrong exit code, ``hang``
when it did not answer in time.

Each category is a function ``(inputs, examples) -> (cases, note)`` listed in
:data:`CATEGORIES`; ``cases`` are ``(what, probe)`` pairs run by
:func:`benchmarks.robustness_inputs.run_cases`. ``tests/robustness/test_verb_promises.py``
runs the same categories on a few generated examples.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from .harness.cases import (
    Outcome,
    Verdict,
    cli_verdict,
    default_bundle_dir,
    run_cli,
    toml_text,
    with_timeout,
    worst,
)
from .harness.stats import MIN_P99_READINGS
from .robustness_inputs import TF_CLI, digest, guarded, mcap_replay, tiny_checkpoint

Case = tuple[str, Callable[[], Verdict]]
Cases = tuple[list[Case], str]

#: seconds a signalled subprocess may take to stop, and to get to work before the signal
STOP_S = 120.0
START_S = 180.0
#: readings a p99 verdict needs (the package's floor; the cases try both sides of it)
FLOOR = MIN_P99_READINGS  # the one definition of "too few" (benchmarks/harness/stats.py)
#: the environment variable a scene names and nobody sets
UNSET_VAR = "TF_ROBUSTNESS_UNSET_PATH"


# ================================================================== shared inputs
@dataclass
class Inputs:
    """What the cases read, made once under ``root``: ``data`` 12 labelled pressed frames
    (``synth --n 12``, no 0 N frame), ``background`` the shipped no-contact DIGIT image in a
    folder of its own, ``bundle`` a copy of the default bundle, ``fp32`` a tiny random-weight
    fp32 RGBmod bundle (None without torch: ``study`` needs the 'export' extra)."""

    root: Path
    data: Path
    background: Path
    bundle: Path
    fp32: Path | None
    note: str = ""

    @classmethod
    def make(cls, root: Path) -> Inputs:
        root.mkdir(parents=True, exist_ok=True)
        data = root / "inputs" / "presses"
        rc, _, err = run_cli(["synth", "--out", str(data), "--n", "12", "--seed", "5", "--no-contact-fraction", "0",
                              "--no-progress"])
        if rc != 0:
            raise RuntimeError(f"synth could not make the labelled frames: {err[-300:]}")
        from tactile_force.edge.synthetic.digit import DEFAULT_BACKGROUND

        bg = root / "inputs" / "no_contact" / "background.png"
        bg.parent.mkdir(parents=True)
        shutil.copy(DEFAULT_BACKGROUND, bg)
        bundle = Path(shutil.copytree(default_bundle_dir(), root / "inputs" / "bundle"))
        fp32, note = None, ""
        try:
            fp32 = tiny_fp32_bundle(root / "inputs" / "fp32")
        except ImportError as exc:
            note = f"study cases not run: {exc} (the 'export' extra)"
        return cls(root, data, bg, bundle, fp32, note)

    def folder(self, name: str) -> Path:
        """A new empty folder for one case."""
        k = 0
        while (p := self.root / "cases" / f"{name}_{k}").exists():
            k += 1
        p.mkdir(parents=True)
        return p

    @functools.cached_property
    def replay(self) -> Path:
        """198 labelled frames: 10 s at --fps 20."""
        return mcap_replay(self.root / "inputs")

    @functools.cached_property
    def teacher(self) -> Path:
        """A tiny RGBmod checkpoint (``compress``'s teacher)."""
        return tiny_checkpoint(self.root / "inputs" / "teacher" / "teacher.pth")

    def earlier(self, verb: str, out: Path | None = None) -> Path:
        """A complete earlier result of ``verb``, made at ``out`` (default: made once under
        ``root``, for cases that copy it: a copy is not the folder its record proves)."""
        out = out if out is not None else self.root / "earlier" / verb
        if not out.is_dir():
            rc, _, err = run_cli(VERBS[verb].argv(self, out))
            if rc not in VERBS[verb].ok_rc or not out.is_dir():
                raise RuntimeError(f"{verb}: could not make an earlier result (exit {rc}): {err[-300:]}")
        return out


def tiny_fp32_bundle(dest: Path) -> Path:
    """A tiny random-weight fp32 RGBmod bundle whose outputs sit near 8 N (RE defined)."""
    import torch
    from tactile_force.export import ExportOptions, ForceNet, ModelSpec, build_model, export_bundle

    torch.manual_seed(0)
    net = ForceNet(build_model("rgbmod", 0.125), ModelSpec("rgbmod", 0.125, 1 / 8))
    with torch.no_grad():
        [m for m in net.modules() if isinstance(m, torch.nn.Linear)][-1].bias.add_(8.0)
    export_bundle(net, dest, ExportOptions(parity_tol_n=1e-3, name="tiny-fp32", trained_on="random weights"))
    return dest


# ================================================================== the verbs that write result folders
@dataclass(frozen=True)
class Verb:
    """A verb writing a folder of results: ``argv(inputs, out)`` a complete small run (no
    --force), ``long_argv(inputs, out)`` one that lasts until a signal stops it, ``reads``
    its input folders and files, ``ok_rc`` the exit codes of a complete run, ``torch`` True
    when it needs the 'export' extra."""

    name: str
    argv: Callable[[Inputs, Path], list[str]]
    long_argv: Callable[[Inputs, Path], list[str]]
    reads: Callable[[Inputs], list[tuple[str, Path]]]
    ok_rc: frozenset[int]
    torch: bool = False


def _bench(i: Inputs, out: Path, frames: int = 100) -> list[str]:
    # 200 fps: the cadence run takes 0.65 s rather than the default 5.5 s
    return ["bench", "--bundle", str(i.bundle), "--data", str(i.data), "--background", str(i.background),
            "--frames", str(frames), "--fps", "200", "--cadence-frames", "100", "--repeats", "1", "--budget-ms", "1000",
            "--out", str(out)]


def _study(i: Inputs, out: Path, frames: int = 5, quick: bool = True) -> list[str]:
    assert i.fp32 is not None
    return (["study", str(i.fp32), "--data", str(i.data), "--background", str(i.background), "--frames", str(frames),
             "--budget-ms", "1000", "--sensitivity-nodes", "0", "--out", str(out)]
            + (["--quick", "--max-configs", "1"] if quick else []))


def _synth(i: Inputs, out: Path, n: int = 12) -> list[str]:
    return ["synth", "--out", str(out), "--n", str(n), "--seed", "1", "--background", str(i.background),
            "--no-progress"]


def _demo(i: Inputs, out: Path, grasps: int = 1) -> list[str]:
    return ["demo", "--out", str(out), "--grasps", str(grasps), "--bundle", str(i.bundle)]


VERBS: dict[str, Verb] = {
    "bench": Verb("bench", _bench, lambda i, o: _bench(i, o, frames=10_000_000),
                  lambda i: [("--bundle", i.bundle), ("--data", i.data), ("--background", i.background)],
                  frozenset({0, 1})),
    "study": Verb("study", _study, lambda i, o: _study(i, o, frames=100, quick=False),
                  lambda i: [("source", i.fp32), ("--data", i.data), ("--background", i.background)]
                  if i.fp32 else [], frozenset({0, 1}), torch=True),
    "synth": Verb("synth", _synth, lambda i, o: _synth(i, o, n=100_000),
                  lambda i: [("--background", i.background)], frozenset({0})),
    "demo": Verb("demo", _demo, lambda i, o: _demo(i, o, grasps=1000), lambda i: [("--bundle", i.bundle)],
                 frozenset({0})),
}


def leftovers(out: Path) -> list[str]:
    """Hidden siblings a verb left beside ``out`` (its staging folder, an old copy)."""
    parent = out.parent
    return sorted(p.name for p in parent.iterdir() if p.name.startswith(f".{out.name}.")) if parent.is_dir() else []


def _with_leftovers(v: Verdict, out: Path) -> Verdict:
    left = leftovers(out)
    if left and v.outcome is not Outcome.DATA_LOST:
        return Verdict(Outcome.SILENT_WRONG, f"hidden staging left beside {out.name}: {left}; {v.detail}")
    return v


def _users_folder(out: Path, own_name: str) -> Path:
    """A folder of the user's own files, one named like a file the verb writes."""
    out.mkdir(parents=True)
    (out / "notes.txt").write_text("my own notes\n")
    (out / own_name).write_text("my own file, not a result\n")
    return out


#: the record a result folder carries (edge/files/record.py; spelled here: the suite also checks older packages)
_MARK = ".tactile-force-output.json"
_OWN_NAME = {"bench": "report.md", "study": "study.md", "synth": "meta.jsonl", "demo": "readings.csv"}


def result_folder_cases(inputs: Inputs, examples: int) -> Cases:
    """--out holding the user's files (without and with --force), an earlier result of the
    same verb with a user's file added (--force), --out = or inside each input, the verb run
    twice without --force: exit 2, every byte kept. An earlier own result with --force: replaced.
    Plots drawn beside an output never replace the user's file of that name."""
    cases: list[Case] = []
    for spec in VERBS.values():
        if not (spec.torch and inputs.fp32 is None):
            cases += _result_cases(inputs, spec)
    return cases + side_file_cases(inputs), inputs.note


def _result_cases(inputs: Inputs, spec: Verb) -> list[Case]:
    """The result-folder cases of one verb."""
    name = spec.name
    reads = [p for _, p in spec.reads(inputs)]

    def users(force: bool) -> Verdict:
        out = _users_folder(inputs.folder(name) / "mine", _OWN_NAME[name])
        argv = spec.argv(inputs, out) + (["--force"] if force else [])
        return _with_leftovers(guarded(argv, [out, *reads], True, ("--out", str(out))), out)

    def earlier() -> Path:  # made in place: --force replaces only the folder its record was made for
        return inputs.earlier(name, inputs.folder(name) / "r")

    def earlier_plus_users() -> Verdict:
        out = earlier()
        sub = next((p for p in sorted(out.rglob("*")) if p.is_dir()), out)
        (sub / "NOTES.txt").write_text("the user's notes on this result\n")
        return _with_leftovers(guarded(spec.argv(inputs, out) + ["--force"], [out, *reads], True,
                                       ("--out", str(out))), out)

    def onto_input(target: Path, inside: bool) -> Verdict:
        out = target / "result" if inside else target
        argv = spec.argv(inputs, out) + ([] if inside else ["--force"])
        return _with_leftovers(guarded(argv, [*reads, target.parent], True, ("--out",)), out)

    def twice() -> Verdict:
        out = earlier()
        return _with_leftovers(guarded(spec.argv(inputs, out), [out, *reads], True, ("--out", "--force")), out)

    def replaced() -> Verdict:
        from tactile_force.edge.files.atomic import foreign_files

        out = earlier()
        before = (digest(out), out.stat().st_ino)  # a same-seed result may repeat the bytes, not the folder
        v = guarded(spec.argv(inputs, out) + ["--force"], reads, False, want_rc=set(spec.ok_rc))
        if v.outcome is Outcome.ACCEPTED and (digest(out), out.stat().st_ino) == before:
            return Verdict(Outcome.SILENT_WRONG, f"--force: success but {out.name} is the earlier result untouched")
        if v.outcome is Outcome.ACCEPTED and (foreign := foreign_files(out, name)):
            return Verdict(Outcome.SILENT_WRONG, f"the new result holds files its record does not list: {foreign}")
        return _with_leftovers(v, out)

    cases: list[Case] = [
        (f"{name} --out <folder of the user's files>", functools.partial(users, False)),
        (f"{name} --out <folder of the user's files> --force", functools.partial(users, True)),
        (f"{name} --out <its earlier result + a user's file> --force", earlier_plus_users),
        (f"{name} twice into the same --out without --force", twice),
        (f"{name} --force over its own earlier result (valid)", replaced)]
    cases += _proof_cases(inputs, spec, earlier) + _claim_cases(inputs, spec)
    for flag, path in spec.reads(inputs):
        if path.is_dir():
            cases += [(f"{name} --out <the {flag} folder> --force", functools.partial(onto_input, path, False)),
                      (f"{name} --out <inside the {flag} folder>", functools.partial(onto_input, path, True))]
        else:
            cases += [(f"{name} --out <the {flag} file> --force", functools.partial(onto_input, path, False)),
                      (f"{name} --out <the folder holding the {flag} file> --force",
                       functools.partial(onto_input, path.parent, False))]
    return cases


def tree(root: Path) -> dict[str, str]:
    """relative path -> sha256 (files), 'dir' (folders), '-> target' (links) of everything under
    ``root``, links not followed (``digest`` misses empty folders and follows links)."""
    if not root.is_dir():
        return {".": digest(root) or "absent"} if not root.is_symlink() else {".": f"-> {os.readlink(root)}"}
    out: dict[str, str] = {}
    for q in sorted(root.rglob("*")):
        rel = str(q.relative_to(root))
        out[rel] = (f"-> {os.readlink(q)}" if q.is_symlink() else "dir" if q.is_dir() else
                    hashlib.sha256(q.read_bytes()).hexdigest())
    return out


def _kept(argv: list[str], out: Path, names: tuple[str, ...], want_rc: frozenset[int] = frozenset({2})) -> Verdict:
    """``argv`` in-process, expected to refuse (exit 2 naming ``names``) and keep everything at
    ``out`` as it was, links and empty folders included (else **data lost**), with no hidden
    sibling left (else **silent wrong**)."""
    before = tree(out)
    v = cli_verdict(argv, set(want_rc), True, names)
    if tree(out) != before:
        gone = sorted(set(before) - set(tree(out)))
        return Verdict(Outcome.DATA_LOST, f"{' '.join(argv[:1])}: {out.name} changed; gone or changed: {gone[:4]}")
    return _with_leftovers(v, out)


def _proof_cases(inputs: Inputs, spec: Verb, earlier: Callable[[], Path]) -> list[Case]:
    """--force over what the record does not prove: a names-only record listing the user's file,
    a copy of an earlier result, a recorded file replaced by a link, an added empty folder, an
    edited file; --out a symbolic link to the user's folder (with and without --force)."""
    name = spec.name

    def names_only() -> Verdict:
        out = _users_folder(inputs.folder(name) / "mine", _OWN_NAME[name])
        (out / _MARK).write_text(json.dumps({"verb": name, "files": ["notes.txt", _OWN_NAME[name]]}))
        return _kept(spec.argv(inputs, out) + ["--force"], out, ("--out", "notes.txt"))

    def copied() -> Verdict:
        out = Path(shutil.copytree(inputs.earlier(name), inputs.folder(name) / "backup", symlinks=True))
        return _kept(spec.argv(inputs, out) + ["--force"], out, ("--out", "another folder"))

    def changed(how: str) -> Verdict:
        out = earlier()
        own = next(p for p in sorted(out.rglob("*")) if p.is_file() and p.name != _MARK)
        rel = str(own.relative_to(out))
        if how == "link":
            mine = out.parent / "my_file.txt"
            mine.write_text("the user's own file\n")
            own.unlink()
            own.symlink_to(mine)
        elif how == "edited":
            data = bytearray(own.read_bytes())
            data[len(data) // 2] ^= 0x01  # same size: only the hash tells
            own.write_bytes(bytes(data))
        else:
            rel = "my_plots"
            (out / rel).mkdir()
        return _kept(spec.argv(inputs, out) + ["--force"], out, ("--out", rel))

    def link(force: bool) -> Verdict:
        d = inputs.folder(name)
        mine = _users_folder(d / "my_folder", _OWN_NAME[name])
        out = d / "link"
        out.symlink_to(mine)
        before = tree(mine)
        v = _kept(spec.argv(inputs, out) + (["--force"] if force else []), out, ("--out", "symbolic link"))
        return v if tree(mine) == before else Verdict(Outcome.DATA_LOST, f"the link's target {mine.name} changed")

    return [(f"{name} --force over a names-only record listing the user's files", names_only),
            (f"{name} --force over a copy of its earlier result (the record proves another folder)", copied),
            (f"{name} --force over its earlier result, a file replaced by a link to the user's file",
             functools.partial(changed, "link")),
            (f"{name} --force over its earlier result, a file edited (same size)",
             functools.partial(changed, "edited")),
            (f"{name} --force over its earlier result + an empty folder", functools.partial(changed, "folder")),
            (f"{name} --out <a symbolic link to the user's folder>", functools.partial(link, False)),
            (f"{name} --out <a symbolic link to the user's folder> --force", functools.partial(link, True))]


def _claim_cases(inputs: Inputs, spec: Verb) -> list[Case]:
    """Two runs at once into the same new --out (the second refused naming it, the first's
    result whole), kill -9 then the same command (nothing hidden left after it), --out a
    mount point and --out under a read-only file system (tmpfs, root only: refused before any
    work, naming --out, never the hidden staging name)."""
    name = spec.name

    def concurrent() -> Verdict:
        out = inputs.folder(name) / "r"
        proc = subprocess.Popen([sys.executable, str(TF_CLI), *spec.long_argv(inputs, out)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        err = _Stderr(proc)
        claim = out.with_name(f".{out.name}.tactile-force-claim")

        def working() -> bool:
            return _AT_WORK[name](out, err.lines, False)

        try:
            end = time.monotonic() + START_S
            while time.monotonic() < end and proc.poll() is None and not working():
                time.sleep(0.05)
            end = time.monotonic() + 5.0  # and holding --out (bench prints its banner a moment before)
            while time.monotonic() < end and proc.poll() is None and not claim.exists():
                time.sleep(0.05)
            if proc.poll() is not None or not working():
                return Verdict(Outcome.HANG, f"the first run was not at work within {START_S:g} s: {err.text()[-200:]}")
            v = cli_verdict(spec.argv(inputs, out), {2}, True, ("--out", "writing it now"))
        finally:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=STOP_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        return _with_leftovers(v, out)

    def killed() -> Verdict:
        out = inputs.folder(name) / "r"
        proc = subprocess.Popen([sys.executable, str(TF_CLI), *spec.long_argv(inputs, out)],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        err = _Stderr(proc)
        end = time.monotonic() + START_S
        while time.monotonic() < end and proc.poll() is None and not _AT_WORK[name](out, err.lines, False):
            time.sleep(0.05)
        proc.kill()
        proc.wait()
        v = guarded(spec.argv(inputs, out), [], False, want_rc=set(spec.ok_rc))
        return _with_leftovers(v, out)

    def mounted(opts: str, inside: bool) -> Verdict:
        d = inputs.folder(name)
        mnt = d / "mnt"
        mnt.mkdir()
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size=4096k{opts}", "tmpfs", str(mnt)],
                           capture_output=True, text=True)
        if r.returncode != 0:
            return Verdict(Outcome.CLEAR, f"not judged: cannot mount a tmpfs ({r.stderr.strip()[:80]})")
        try:
            out = mnt / "r" if inside else mnt
            what = "read-only" if inside else "mount point"
            v = _kept(spec.argv(inputs, out), out, ("--out", what))
            if ".partial" in v.detail:
                return Verdict(Outcome.TRACEBACK, f"the message names the hidden staging folder: {v.detail}")
            return v
        finally:
            subprocess.run(["umount", str(mnt)], capture_output=True)

    cases: list[Case] = [(f"{name} twice at once into the same new --out", concurrent),
                         (f"kill -9 during {name}, then the same command", killed)]
    if hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("mount"):
        cases += [(f"{name} --out <a mount point (tmpfs)>", functools.partial(mounted, "", False)),
                  (f"{name} --out <inside a read-only tmpfs>", functools.partial(mounted, ",ro", True))]
    return cases


def side_file_cases(inputs: Inputs) -> list[Case]:
    """A verb that draws a plot beside its output (``calibrate-force``: ``<out>_calibration.png``,
    ``run --out r.csv``: ``r_force_vs_time.png``) where the user already has a file of that name:
    kept byte for byte (exit 2 naming it, or the plot not drawn)."""

    def calibrate() -> Verdict:
        d = inputs.folder("side")
        plot = d / "cal_calibration.png"
        plot.write_bytes(b"the user's own figure")
        return _either(["calibrate-force", str(inputs.bundle), "--data", str(inputs.data), "--out", str(d / "cal")],
                       [plot, inputs.data], {0}, (plot.name,))

    def run() -> Verdict:
        d = inputs.folder("side")
        plot = d / "r_force_vs_time.png"
        plot.write_bytes(b"the user's own figure")
        return _either(["run", "--source", str(inputs.data), "--out", str(d / "r.csv")], [plot, inputs.data], {0},
                       (plot.name,))

    return [("calibrate-force --out C beside the user's own C_calibration.png", calibrate),
            ("run --out r.csv beside the user's own r_force_vs_time.png", run)]


# ================================================================== interruption
class _Stderr:
    """Collects a subprocess's stderr lines in a thread (the pipe never fills up)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, args=(proc,), daemon=True)
        self._t.start()

    def _read(self, proc: subprocess.Popen) -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            self.lines.append(line)

    def text(self) -> str:
        self._t.join(5.0)
        return "".join(self.lines)


def _staging(out: Path) -> list[Path]:
    return [out.parent / n for n in leftovers(out)]


def _csv_lines(path: Path) -> int:
    try:
        return len(path.read_text().splitlines())
    except (OSError, UnicodeDecodeError):
        return 0


def _writing(out: Path, previous: bool) -> list[Path]:
    """Where a verb writes its result: its hidden staging folder(s), else (no earlier result
    there) ``out`` itself."""
    return _staging(out) + ([] if previous else [out])


#: verb -> is it at work? (its --out, its stderr lines so far, whether --out holds an earlier result)
AtWork = Callable[[Path, list[str], bool], bool]
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


# ================================================================== statistics floor
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


# ================================================================== labelled data judged before work
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


def _either(argv: list[str], watched: list[Path], ok_rc: set[int], names: tuple[str, ...]) -> Verdict:
    """A case either answer fits: a complete run (exit in ``ok_rc``) or exit 2 naming ``names``."""
    before = {p: digest(p) for p in watched}

    def answer() -> Verdict:
        rc, out, err = run_cli(argv)
        if "Traceback" in out + err:
            return Verdict(Outcome.TRACEBACK, "printed a traceback")
        if rc in ok_rc:
            return Verdict(Outcome.ACCEPTED, f"exit {rc}")
        if rc == 2 and all(n in out + err for n in names):
            return Verdict(Outcome.CLEAR, f"exit 2: {err.strip()[-160:]}")
        return Verdict(Outcome.TRACEBACK, f"exit {rc} (expected {sorted(ok_rc)} or 2 naming {names}): {err[-200:]}")

    v = with_timeout(answer, 180.0)
    if changed := [str(p) for p in watched if digest(p) != before[p]]:
        return Verdict(Outcome.DATA_LOST, f"input changed: {changed}")
    return v


def labelled_cases(inputs: Inputs, examples: int) -> Cases:
    """bench --data, study --data, calibrate-force --data and run --source on labelled frames
    holding one bad image: exit 2 naming the file before any work."""
    verbs = ["bench", "calibrate-force", "run"] + (["study"] if inputs.fp32 is not None else [])
    return [(f"{verb}: {what}", functools.partial(probe_labelled, inputs, verb, write, must))
            for what, write, must in _bad_images() for verb in verbs], inputs.note


# ================================================================== Python API argument types
def _options_classes() -> list[type]:
    from tactile_force.edge.gate import GateOptions
    from tactile_force.edge.runtime import RuntimeOptions

    return [GateOptions, RuntimeOptions]


def _kind(annotation: Any) -> str:
    a = str(annotation).replace(" ", "")
    return {"int": "int", "float": "float", "bool": "bool", "bool|None": "bool|None", "int|None": "int|None",
            "Literal['auto',True,False]": "auto|bool"}.get(a, a)


_COMMON_WRONG = st.one_of(st.text(max_size=6), st.lists(st.integers(0, 3), max_size=2),
                          st.dictionaries(st.text(max_size=2), st.integers(0, 3), max_size=1), st.binary(max_size=3),
                          st.sampled_from([1j, "5", "true", "false", "nan", (1,), b"1"]))


def wrong_values(kind: str) -> st.SearchStrategy[Any]:
    """Values of the wrong type for a field annotated ``kind``."""
    if kind == "int":
        return st.one_of(_COMMON_WRONG, st.none(), st.booleans(),
                         st.floats().filter(lambda v: not (math.isfinite(v) and v == int(v))))
    if kind == "int|None":
        return st.one_of(_COMMON_WRONG, st.booleans(),
                         st.floats().filter(lambda v: not (math.isfinite(v) and v == int(v))))
    if kind == "float":
        return st.one_of(_COMMON_WRONG, st.none(), st.booleans())
    if kind == "bool":
        return st.one_of(_COMMON_WRONG, st.none(), st.integers(-2, 2), st.floats())
    if kind == "bool|None":
        return st.one_of(_COMMON_WRONG, st.integers(-2, 2), st.floats())
    if kind == "auto|bool":
        return st.one_of(_COMMON_WRONG.filter(lambda v: v != "auto"), st.none(), st.integers(-2, 2), st.floats())
    raise ValueError(f"no wrong values for {kind!r}")


@st.composite
def wrong_options(draw: Callable[[st.SearchStrategy[Any]], Any]) -> tuple[str, str, Any]:
    """(class name, field, a wrong-typed value) for a field of GateOptions or RuntimeOptions."""
    cls = draw(st.sampled_from(_options_classes()))
    f = draw(st.sampled_from(dataclasses.fields(cls)))
    return cls.__name__, f.name, draw(wrong_values(_kind(f.type)))


def _valid(kind: str, default: Any) -> Any:
    """A value of the right type that is not a plain Python one (numpy) or flips a flag."""
    return {"int": lambda: np.int64(default), "float": lambda: np.float64(default), "bool": lambda: not default,
            "bool|None": lambda: True, "int|None": lambda: np.int64(1 if default is None else default),
            "auto|bool": lambda: np.bool_(False)}[kind]()


def _accepts(error: BaseException) -> bool:
    from tactile_force.edge.errors import TactileForceError

    return isinstance(error, (TactileForceError, TypeError))


def probe_construct(what: str, make: Callable[[], object], names: tuple[str, ...], bad: bool) -> Verdict:
    """``make()`` must raise a TactileForceError (or TypeError) naming ``names`` when ``bad``,
    and succeed otherwise."""
    try:
        made = make()
    except BaseException as exc:  # noqa: BLE001 - classified
        msg = str(exc)
        if not _accepts(exc):
            return Verdict(Outcome.TRACEBACK, f"{what}: {type(exc).__name__}: {msg}"[:300])
        if not bad:
            return Verdict(Outcome.VALID_REFUSED, f"{what}: {type(exc).__name__}: {msg}"[:300])
        if missing := [n for n in names if n not in msg]:
            return Verdict(Outcome.TRACEBACK, f"{what}: {type(exc).__name__} does not name {missing}: {msg}"[:300])
        return Verdict(Outcome.CLEAR, f"{what}: {msg}"[:300])
    close = getattr(made, "close", None)
    if callable(close):
        close()
    return Verdict(Outcome.SILENT_WRONG if bad else Outcome.ACCEPTED,
                   f"{what}: " + ("accepted at construction" if bad else "constructed"))


def probe_option(cls_name: str, field: str, value: Any, bad: bool = True) -> Verdict:
    cls = next(c for c in _options_classes() if c.__name__ == cls_name)
    return probe_construct(f"{cls_name}({field}={value!r})"[:120], lambda: cls(**{field: value}), (field,), bad)


def drawn(strategy: st.SearchStrategy[Any], n: int) -> list[Any]:
    """``n`` examples of ``strategy``, the same on every run (derandomized hypothesis)."""
    got: list[Any] = []

    @settings(max_examples=n, deadline=None, database=None, derandomize=True, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def collect(x: Any) -> None:
        got.append(x)

    collect()
    return got


def api_cases(inputs: Inputs, examples: int) -> Cases:
    """The API calls a user gets wrong (fixed list; ``GateOptions(threshold='x')`` and
    ``RuntimeOptions(deadline_ms='x')`` among every field of GateOptions and RuntimeOptions
    given "x"), a right-typed value for each field, then ``examples`` generated wrong-typed
    values: a TactileForceError (or TypeError) naming the parameter, at construction."""
    from tactile_force.edge.gate import ContactGate, GateOptions
    from tactile_force.edge.model import OnnxForceModel
    from tactile_force.edge.runtime import ForceRuntime, Sensor
    from tactile_force.edge.sources import ReplayFolderSource

    bundle = str(inputs.bundle)

    def sensor() -> Sensor:
        return Sensor("left", ReplayFolderSource(inputs.data), ContactGate())

    def model() -> OnnxForceModel:
        return OnnxForceModel(bundle, warmup=0)

    fixed: list[tuple[str, Callable[[], object], tuple[str, ...], bool]] = [
        ("ForceRuntime(model=None)", lambda: ForceRuntime([sensor()], None), ("model",), True),
        ("ForceRuntime(sensors=<a Sensor>)", lambda: ForceRuntime(sensor(), model()), ("sensors",), True),
        ("ForceRuntime(sensors=['left'])", lambda: ForceRuntime(["left"], model()), ("sensors",), True),
        ("ForceRuntime(options=GateOptions())", lambda: ForceRuntime([sensor()], model(), GateOptions()),
         ("options",), True),
        ("Sensor(source='folder')", lambda: Sensor("left", "folder", ContactGate()), ("source",), True),
        ("Sensor(gate=GateOptions())", lambda: Sensor("left", ReplayFolderSource(inputs.data), GateOptions()),
         ("gate",), True),
        ("OnnxForceModel(threads='2')", lambda: OnnxForceModel(bundle, threads="2"), ("threads",), True),
        ("OnnxForceModel(bundle=None)", lambda: OnnxForceModel(None), ("bundle",), True),
        ("ContactGate('x')", lambda: ContactGate("x"), ("options",), True),
        ("ForceRuntime([Sensor(...)], OnnxForceModel(...)) (valid)", lambda: ForceRuntime([sensor()], model()), (),
         False),
    ]
    cases: list[Case] = [(what, functools.partial(probe_construct, what, make, names, bad))
                         for what, make, names, bad in fixed]
    for cls in _options_classes():
        for f in dataclasses.fields(cls):
            kind = _kind(f.type)
            cases.append((f"{cls.__name__}({f.name}='x')", functools.partial(probe_option, cls.__name__, f.name, "x")))
            good = _valid(kind, f.default)
            cases.append((f"{cls.__name__}({f.name}={good!r}) (valid)",
                          functools.partial(probe_option, cls.__name__, f.name, good, False)))
    for cls_name, field, value in drawn(wrong_options(), examples):
        cases.append((f"{cls_name}({field}={value!r})"[:100], functools.partial(probe_option, cls_name, field, value)))
    return cases, ""


# ================================================================== honest states
def _edited_bundle(src: Path, dest: Path, path: tuple[str, ...], value: Any) -> Path:
    """A copy of the bundle ``src`` whose model.json says ``value`` at ``path`` (the graph's
    hash, all the manifest's sha256 covers, still matches)."""
    b = Path(shutil.copytree(src, dest))
    m = json.loads((b / "model.json").read_text())
    t = m
    for k in path[:-1]:
        t = t[k]
    t[path[-1]] = value
    (b / "model.json").write_text(json.dumps(m, indent=1))
    return b


def probe_verify(inputs: Inputs, src: Path, path: tuple[str, ...], value: Any) -> Verdict:
    """``bundle verify`` on a manifest claiming ``value`` at ``path``: exit 1 naming the field
    or the claim (exit 0 for an unedited copy)."""
    d = inputs.folder("verify")
    if not path:
        b = Path(shutil.copytree(src, d / "b"))
        return with_timeout(lambda: _verify(b, False, ()), 120.0)
    b = _edited_bundle(src, d / "b", path, value)
    return with_timeout(lambda: _verify(b, True, (path[-1], str(value))), 120.0)


def _verify(bundle: Path, lie: bool, names: tuple[str, ...]) -> Verdict:
    rc, out, err = run_cli(["bundle", "verify", str(bundle)])
    text = out + err
    if "Traceback" in text:
        return Verdict(Outcome.TRACEBACK, "bundle verify printed a traceback")
    if not lie:
        return Verdict(Outcome.ACCEPTED if rc == 0 else Outcome.VALID_REFUSED, f"exit {rc}: {text.strip()[-160:]}")
    if rc == 0:
        return Verdict(Outcome.SILENT_WRONG, f"exit 0 for a manifest claiming {names[-1]}: {text.strip()[-160:]}")
    if rc != 1:
        return Verdict(Outcome.TRACEBACK, f"exit {rc}, expected 1 (a check failed): {err[-200:]}")
    if not any(n in err for n in names):
        return Verdict(Outcome.TRACEBACK, f"the message names neither {names}: {err[-200:]}")
    return Verdict(Outcome.CLEAR, err.strip()[-200:])


def probe_learning(inputs: Inputs, background_frames: int | None) -> Verdict:
    """A replay of pressed frames without a background (``run --source``, or a scene with
    ``gate.background_frames``): every reading made while the background is learnt has
    interval ``unknown`` and no bounds."""
    d = inputs.folder("learning")
    csv, jsonl = d / "r.csv", d / "r.jsonl"
    if background_frames is None:
        argv = ["run", "--source", str(inputs.data), "--out", str(csv), "--out", str(jsonl)]
    else:
        scene = d / "scene.toml"
        scene.write_text(toml_text({
            "runtime": {"bundle": str(inputs.bundle)}, "gate": {"background_frames": background_frames},
            "sensor": [{"name": "digit", "source": "replay", "path": str(inputs.data)}],
            "output": [{"kind": "csv", "path": str(csv)}, {"kind": "jsonl", "path": str(jsonl)}]}))
        argv = ["run", "--scene", str(scene)]
    v = guarded(argv, [inputs.data], False)
    if v.outcome is not Outcome.ACCEPTED:
        return v
    try:
        rows = [json.loads(ln) for ln in jsonl.read_text().splitlines() if ln.strip()]
        import csv as csv_mod

        with open(csv) as fh:
            csv_rows = list(csv_mod.DictReader(fh))
    except (OSError, ValueError) as exc:
        return Verdict(Outcome.TRACEBACK, f"readings unreadable: {exc}")
    learning = [k for k, r in enumerate(rows) if "learning" in str(r.get("detail", ""))]
    if not learning:
        return Verdict(Outcome.TRACEBACK, f"no reading says it was made while learning ({len(rows)} readings)")
    wrong = [k for k in learning if rows[k]["interval"] != "unknown" or rows[k]["force_low_n"] is not None
             or rows[k]["force_high_n"] is not None or csv_rows[k]["interval"] != "unknown"]
    if wrong:
        r = rows[wrong[0]]
        return Verdict(Outcome.SILENT_WRONG, f"{len(wrong)} of {len(learning)} learning readings claim an interval, "
                                             f"e.g. frame {r['frame_index']}: {r['interval']} "
                                             f"[{r['force_low_n']}, {r['force_high_n']}] N, truth {r['truth_n']} N")
    return Verdict(Outcome.ACCEPTED, f"{len(learning)} learning readings, all interval unknown")


def probe_scene_show(inputs: Inputs, kind: str) -> Verdict:
    """``scene show`` on a scene ``run`` refuses at once: both exit 2 naming the problem, and
    ``run`` changes nothing."""
    d = inputs.folder("scene_show")
    os.environ.pop(UNSET_VAR, None)
    out = d / "readings.csv"
    sensor: dict[str, Any] = {"name": "digit", "source": "replay", "path": str(inputs.data)}
    watched: list[Path] = [inputs.data]
    if kind == "unset $VAR in an output path":
        out = d / f"${UNSET_VAR}" / "readings.csv"
        names: tuple[str, ...] = (UNSET_VAR,)
    elif kind == "unset $VAR in the replay path":
        sensor["path"] = f"${{{UNSET_VAR}}}/presses"
        names = (UNSET_VAR,)
    elif kind == "an existing output (no --force)":
        out.write_text("yesterday's readings\n")
        watched.append(out)
        names = (str(out),)
    elif kind == "an output inside the replay folder":
        out = Path(shutil.copytree(inputs.data, d / "presses")) / "readings.csv"
        sensor["path"] = str(out.parent)
        watched = [out.parent]
        names = (str(out),)
    elif kind == "an output that is the background":
        bg = Path(shutil.copy(inputs.background, d / "background.png"))
        sensor["background"] = str(bg)
        out = bg
        watched.append(bg)
        names = (str(bg),)
    elif kind == "a camera that is not there":
        sensor = {"name": "digit", "source": "camera", "device": "/dev/video-robustness-none"}
        names = ("/dev/video-robustness-none",)
    else:
        raise ValueError(kind)
    scene = d / "scene.toml"
    scene.write_text(toml_text({"runtime": {"bundle": str(inputs.bundle)}, "sensor": [sensor],
                                "output": [{"kind": "csv", "path": str(out)}]}))
    ran = guarded(["run", "--scene", str(scene), "--max-frames", "3"], watched, True, names, timeout_s=60.0)
    if ran.outcome is Outcome.DATA_LOST:
        return ran
    shown = guarded(["scene", "show", str(scene)], watched, True, names, timeout_s=60.0)
    if shown.outcome is Outcome.SILENT_WRONG and ran.outcome is Outcome.CLEAR:
        return Verdict(Outcome.SILENT_WRONG, f"scene show exit 0, run refuses: {ran.detail}")
    return worst([Verdict(ran.outcome, f"run: {ran.detail}"), Verdict(shown.outcome, f"scene show: {shown.detail}")])


SCENE_KINDS = ("unset $VAR in an output path", "unset $VAR in the replay path", "an existing output (no --force)",
               "an output inside the replay folder", "an output that is the background", "a camera that is not there")


def honest_cases(inputs: Inputs, examples: int) -> Cases:
    """bundle verify on manifests contradicting their graph, learning-time intervals, and
    scene show answering as run does."""
    default = default_bundle_dir()
    claims: list[tuple[Path, str, tuple[str, ...], Any]] = [(default, "the shipped default bundle", (), None)]
    claims += [(default, "default (int8-static)", ("precision",), p) for p in ("int8-dynamic", "fp16", "fp32")]
    claims += [(default, "default (input scale 0.25)", ("architecture", "input_scale"), s) for s in (0.125, 0.5, 1.0)]
    if inputs.fp32 is not None:
        claims.append((inputs.fp32, "tiny fp32", (), None))
        claims += [(inputs.fp32, "tiny fp32", ("precision",), p) for p in ("int8-static", "int8-dynamic", "fp16")]
        claims.append((inputs.fp32, "tiny fp32 (input scale 0.125)", ("architecture", "input_scale"), 0.25))
    cases: list[Case] = []
    for src, what, path, value in claims:
        label = f"bundle verify: {what}, manifest " + (f"{'.'.join(path)} = {value}" if path else "unedited (valid)")
        cases.append((label, functools.partial(probe_verify, inputs, src, path, value)))
    cases += [("run without --background: readings while learning", functools.partial(probe_learning, inputs, None)),
              ("scene with gate.background_frames = 9, no background: readings while learning",
               functools.partial(probe_learning, inputs, 9))]
    cases += [(f"scene show vs run: {k}", functools.partial(probe_scene_show, inputs, k)) for k in SCENE_KINDS]
    return cases, inputs.note if inputs.fp32 is None else ""


#: (key, category name, case builder), in the catalogue's order
CATEGORIES: list[tuple[str, str, Callable[[Inputs, int], Cases]]] = [
    ("result_folders", "result folders (bench, study, synth, demo: the user's files, earlier results, --out onto "
                       "inputs; plots beside an output)", result_folder_cases),
    ("interruption", "interrupted verbs (SIGINT / SIGTERM during bench, study, synth, demo, run, compress)",
     signal_cases),
    ("statistics_floor", "statistics floor (bench / study --frames 1, 5, 50, 99, 100)", floor_cases),
    ("labelled_data", "labelled data judged before work (bad images for bench, study, calibrate-force, run)",
     labelled_cases),
    ("api_types", "Python API argument types (fixed calls; generated wrong types for GateOptions, RuntimeOptions)",
     api_cases),
    ("honest_states", "honest states (bundle verify claims, learning-time intervals, scene show as run)",
     honest_cases),
]
