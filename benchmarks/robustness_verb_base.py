"""What the verb-promise categories share (benchmarks/robustness_verbs.py lists them): the inputs made
once (:class:`Inputs`), the verbs that write result folders (:data:`VERBS`) and the checks every
category runs on a folder after a verb (leftovers, the user's files kept, the captured stderr)."""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import subprocess
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from .harness.cases import (
    Outcome,
    Verdict,
    cli_verdict,
    default_bundle_dir,
    run_cli,
    with_timeout,
)
from .harness.stats import MIN_P99_READINGS
from .robustness_inputs import digest, tiny_checkpoint
from .robustness_mcap import mcap_replay

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
