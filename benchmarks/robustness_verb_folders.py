"""Verb promises: result folders. ``bench``, ``study``, ``synth`` and ``demo`` keep the user's files and
earlier results, refuse ``--out`` onto their inputs and replace a result only with ``--force``."""

from __future__ import annotations

import functools
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from .harness.cases import (
    Outcome,
    Verdict,
    cli_verdict,
)
from .robustness_inputs import TF_CLI, digest, guarded
from .robustness_verb_base import (
    _MARK,
    _OWN_NAME,
    START_S,
    STOP_S,
    VERBS,
    Case,
    Cases,
    Inputs,
    Verb,
    _either,
    _kept,
    _Stderr,
    _users_folder,
    _with_leftovers,
    tree,
)

# ================================================================== shared inputs
from .robustness_verb_signals import _AT_WORK


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
