"""Robustness catalogue: bad inputs and faults, each run and classified.

    python -m benchmarks robustness            # every category -> docs/robustness.md
    python -m benchmarks robustness --quick    # fewer generated cases, prints the table only

Every case is run through the public API (or the CLI in-process) and classified as one of

* ``accepted``      valid input, accepted with the right result;
* ``clear error``   invalid input refused with a TactileForceError naming the input;
* ``valid refused`` valid input refused (a false alarm, counted apart);
* ``traceback``     any other exception (or a CLI traceback / wrong exit code);
* ``silent wrong``  invalid input accepted, or a wrong value returned;
* ``hang``          no answer within the case's time limit;
* ``data lost``     a fault (kill -9, full disk, truncation) cost a complete sample.

Generated categories use hypothesis strategies (the same ones tests/robustness uses), so
the counts and the tests exercise the same cases. The fault cases are fixed lists.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import signal
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from .harness.cases import (  # noqa: F401 - the suite's tests import these from here too
    BAD,
    Outcome,
    Verdict,
    accepted,
    cli_verdict,
    default_bundle_dir,
    make_dataset,
    refusal,
    run_cli,
    toml_text,
    with_timeout,
    worst,
    write_frame_png,
)
from .harness.paths import require_repo
from .robustness_contracts import (  # noqa: F401 - categories, imported here for the catalogue and the tests
    _DTYPES,
    _META_VALUES,
    _MUST_MATCH,
    _SHAPES,
    _base_manifest_text,
    _materialise,
    _paths,
    base_manifest,
    base_scene,
    calib_channel_cases,
    checkpoint_metas,
    cli_cases,
    expected_meta_ok,
    exposure_patterns,
    frame_inputs,
    json_values,
    manifest_mutations,
    manifest_paths,
    probe_calib_channels,
    probe_checkpoint_meta,
    probe_exposure,
    probe_frame,
    probe_manifest,
    probe_scene,
    scene_mutations,
    targeted_manifests,
    targeted_scenes,
    toml_values,
)
from .robustness_data import (  # noqa: F401 - categories, imported here for the catalogue and the tests
    _LABEL_TOKENS,
    MAX_FORCE_N,
    _Count,
    expected_label,
    expected_meta,
    label_bytes,
    meta_bytes,
    probe_label,
    probe_meta,
)
from .robustness_faults import (  # noqa: F401 - categories, imported here for the catalogue and the tests
    KILL_AFTER,
    KILL_PHASES,
    KILL_WORKER,
    FixedScale,
    NoiseFrames,
    _record_cli_with_fakes,
    probe_disk_full,
    probe_kill,
    probe_replay_vanish,
    probe_truncation,
    small_filesystem,
)

REPO = require_repo("the robustness suite (its workers are in tests/robustness)")
DOCS = REPO / "docs" / "robustness.md"


def use_package_root(root: str | os.PathLike) -> None:
    """Import ``tactile_force`` from ``root`` (a folder holding tactile_force/edge, /export,
    /firmware_bridge) instead of the installed package: used to run a test against an older
    commit's package (tests/robustness/tf_cli.py). Call before tactile_force is imported."""
    for name in [m for m in sys.modules if m == "tactile_force" or m.startswith("tactile_force.")]:
        del sys.modules[name]  # imported before (by this suite's own modules): import again from root
    sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in repr(f).lower()]
    sys.path[:] = [p for p in sys.path if "__editable__" not in p]
    sys.path.insert(0, str(root))
    os.environ["TF_PACKAGE_ROOT"] = str(root)  # the kill -9 worker subprocess follows




# =============================================================================== the catalogue
@dataclass
class Tally:
    category: str
    counts: dict[Outcome, int] = field(default_factory=lambda: {o: 0 for o in Outcome})
    bad: list[str] = field(default_factory=list)
    note: str = ""

    def add(self, v: Verdict) -> None:
        self.counts[v.outcome] += 1
        if not v.ok and len(self.bad) < 5:
            self.bad.append(str(v))

    @property
    def total(self) -> int:
        return sum(self.counts.values())


def _hyp(strategy: st.SearchStrategy, n: int, fn: Callable[[Any], Verdict], tally: Tally) -> None:
    @settings(max_examples=n, deadline=None, database=None, derandomize=True,
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def run(x: Any) -> None:
        tally.add(with_timeout(lambda: fn(x), 60.0))

    run()


def run_catalogue(examples: int = 100, log: Callable[[str], None] = print) -> list[Tally]:
    """Every category; ``examples`` generated cases per generated category."""
    tallies: list[Tally] = []
    with tempfile.TemporaryDirectory(prefix="tf_robust_") as tmp:
        base = Path(tmp)

        def category(name: str) -> Tally:
            t = Tally(name)
            tallies.append(t)
            log(f"[{len(tallies)}] {name} ...")
            return t

        t = category("label files (force_N.txt: 4 readers each)")
        root = make_dataset(base / "labels")
        _hyp(label_bytes(), examples, lambda d: probe_label(root, d), t)
        for tok in _LABEL_TOKENS:
            t.add(probe_label(root, tok))

        t = category("meta.jsonl")
        mroot = make_dataset(base / "meta", n=2)
        _hyp(meta_bytes(), examples, lambda d: probe_meta(mroot, d), t)

        t = category("frames (check_frame)")
        _hyp(frame_inputs(), examples, probe_frame, t)

        t = category("exposure check (fine patterns)")
        _hyp(exposure_patterns(), examples, probe_exposure, t)

        t = category("bundle manifests (load_bundle; bundle verify/show on the targeted ones)")
        mfolder = base / "bundle"
        mfolder.mkdir()
        shutil.copy(default_bundle_dir() / "model.onnx", mfolder / "model.onnx")
        _hyp(manifest_mutations(), examples, lambda c: probe_manifest(mfolder, c), t)
        for case in targeted_manifests():
            t.add(probe_manifest(mfolder, case, cli=True))

        t = category("scenes (load_scene)")
        sfolder = base / "scene"
        sfolder.mkdir()
        _hyp(scene_mutations(), examples, lambda c: probe_scene(sfolder, c), t)
        for what, mutate, must in targeted_scenes():
            v = probe_scene(sfolder, (what, mutate))
            if must and v.outcome is Outcome.ACCEPTED:
                v = Verdict(Outcome.SILENT_WRONG, f"accepted {what}")
            t.add(v)

        t = category("checkpoint metadata")
        cfolder = base / "ckpt"
        cfolder.mkdir()
        _hyp(checkpoint_metas(), examples, lambda m: probe_checkpoint_meta(cfolder, m), t)

        t = category("CLI arguments and calibration frames")
        afolder = base / "args"
        afolder.mkdir()
        for argv, codes, names in cli_cases(afolder):
            t.add(cli_verdict(argv, codes, True, names))
        for _what, variant, path in calib_channel_cases(afolder):
            t.add(probe_calib_channels(variant, path))

        t = category("record: kill -9 at each write phase, then resume")
        for phase in KILL_PHASES:
            t.add(probe_kill(base, phase))

        t = category("record: meta.jsonl cut at every byte of its last line, then --repair")
        data_len = len(json.dumps({"id": 3, "k": 3})) + 1
        for cut in range(data_len + 1):
            t.add(probe_truncation(base, cut))

        t = category("record: disk full")
        v, method = probe_disk_full(base)
        t.add(v)
        t.note = method

        t = category("replay folder deleted mid-run")
        for paced in (False, True):
            t.add(probe_replay_vanish(base, paced))

        from . import robustness_inputs as i19
        from . import robustness_mcap as mc

        t = category("inputs never destroyed (each writing verb aimed at its inputs, --force included)")
        ifolder = base / "inputs"
        ifolder.mkdir()
        i19.run_cases(i19.inputs_cases(ifolder), t.add)

        t = category("labelled presses (duplicates, colliding names, .jpg, comma, unit, x10, FIFO)")
        pfolder = base / "presses"
        pfolder.mkdir()
        i19.run_cases(i19.presses_cases(pfolder), t.add)

        depth = i19.depth_cases(base)
        t = category("calibrate-depth radius and scale")
        if depth:
            i19.run_cases(depth, t.add)
        else:
            t.note = "not run: the shared ball-press data is absent"

        t = category("MCAP log of a run stopped by SIGTERM, SIGINT, kill -9 (mcap library readers)")
        if mc.mcap_available():
            replay = mc.mcap_replay(base)
            for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGKILL):
                t.add(mc.probe_mcap_signal(base, replay, sig))
        else:
            t.note = "not run: the 'mcap' extra is not installed"

        t = category("smaller items (--max-frames 0, scene topic, VGA background, depth mapping, nan flags)")
        sm = base / "smaller"
        sm.mkdir()
        i19.run_cases(i19.smaller_cases(sm), t.add)

        from . import robustness_bundles as rb

        t = category("bundles bundle verify refuses (load_bundle, run, verify) and their records' own consistency")
        rb_folder = base / "verify_refuses"
        rb_folder.mkdir()
        i19.run_cases(rb.bundle_cases(rb_folder), t.add)
        t = category("scene paths (a folder, a FIFO, a dangling link; a path variable unset or empty)")
        i19.run_cases(rb.scene_path_cases(base / "scene_paths"), t.add)

        from . import robustness_runtime as rr

        t = category("runtime parts (a gate, its copy or a source under two sensors; a source lacking read / close)")
        i19.run_cases(rr.part_cases(), t.add)
        t = category("warm-up waits (frames stamped with the wall clock or a clock 0.3 s ahead, warm-ups on)")
        i19.run_cases(rr.wait_cases(), t.add)

        from . import robustness_verbs as verbs

        inputs: verbs.Inputs | Exception
        try:
            inputs = verbs.Inputs.make(base / "verbs")
        except Exception as exc:  # noqa: BLE001 - a package that cannot make them fails every category below
            inputs = exc
        for _key, name, build in verbs.CATEGORIES:
            t = category(name)
            try:
                if isinstance(inputs, Exception):
                    raise inputs
                cases, t.note = build(inputs, examples)
            except Exception as exc:  # noqa: BLE001 - classified, never propagated
                t.add(Verdict(Outcome.TRACEBACK, f"no cases: {type(exc).__name__}: {exc}"[:300]))
                continue
            i19.run_cases(cases, t.add)

        from . import robustness_cli as cli  # the CLI's own promises: signals, numbers, old names, bench statistics

        for _key, name, build_cli in cli.CATEGORIES:
            t = category(name)
            clifolder = base / f"cli_{_key}"
            clifolder.mkdir()
            try:
                cases, t.note = build_cli(clifolder, examples)
            except Exception as exc:  # noqa: BLE001 - classified, never propagated
                t.add(Verdict(Outcome.TRACEBACK, f"no cases: {type(exc).__name__}: {exc}"[:300]))
                continue
            i19.run_cases(cases, t.add)
    return tallies


COLUMNS = [Outcome.ACCEPTED, Outcome.CLEAR, Outcome.VALID_REFUSED, Outcome.TRACEBACK, Outcome.SILENT_WRONG,
           Outcome.HANG, Outcome.DATA_LOST]


def table(tallies: list[Tally]) -> str:
    head = ["category", "cases"] + [c.value for c in COLUMNS]
    rows = [[t.category, str(t.total)] + [str(t.counts[c]) for c in COLUMNS] for t in tallies]
    tot = ["**all**", str(sum(t.total for t in tallies))] + [str(sum(t.counts[c] for t in tallies)) for c in COLUMNS]
    rows.append(tot)
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out)


def failures(tallies: list[Tally]) -> list[str]:
    return [f"{t.category}: {b}" for t in tallies for b in t.bad]


# =============================================================================== the page
#: the line between the generated counts and the page's hand-kept rules and findings
MARK = "<!-- Above: written by `python -m benchmarks robustness`. Below: the rules and findings, kept by hand. -->"


def page(tallies: list[Tally], command: str, examples: int, kept: str = "") -> str:
    """The page: command, commit, machine, the counts and any case that went wrong, then
    ``kept`` (the page's hand-kept rules and findings, from :data:`MARK` on)."""
    from .harness.machine import describe_machine, header

    disk = next((t.note for t in tallies if t.note), "")
    bad = failures(tallies)
    lines = [header("Robustness: bad inputs and faults", command, describe_machine(),
                    "Every case goes through the public API or the CLI, as a user would; the rules each "
                    "category is judged by are below the table. The hand-picked cases (command lines, "
                    "manifest, bundle and scene edits, the values generated cases draw from) are the rows of "
                    "benchmarks/robustness_cases.toml."),
             f"{examples} generated cases per generated category.", "", table(tallies), "",
             f"Disk full was made with: {disk}.", ""]
    if bad:
        lines += ["## Cases that went wrong", ""] + [f"* {b}" for b in bad] + [""]
    return "\n".join(lines) + "\n" + (kept or MARK + "\n")


def run(args, argv: list[str]) -> int:
    """``python -m benchmarks robustness``: run the catalogue, print the table, write the page.
    Exit 1 when any case is a traceback, silent wrong, hang, data lost or valid refused."""
    from .harness.machine import command_line

    examples = 15 if args.quick else args.examples
    out = Path(args.out)
    if args.quick and out.resolve().is_relative_to((REPO / "docs").resolve()):
        print(f"--quick results are a smoke run and never go into the docs; pick another --out than {out}",
              file=sys.stderr)
        return 2
    logging.getLogger("tactile_force").addHandler(logging.NullHandler())  # warnings are counted, not printed
    tallies = run_catalogue(examples, log=lambda s: print(s, flush=True))
    print(table(tallies))
    for b in failures(tallies):
        print(f"  ! {b}")
    out.mkdir(parents=True, exist_ok=True)
    dest = out / "robustness.md"
    kept = DOCS.read_text() if DOCS.is_file() else ""
    kept = kept[kept.index(MARK):] if MARK in kept else ""
    dest.write_text(page(tallies, command_line(argv), examples, kept))
    print(f"wrote {dest}")
    return 1 if failures(tallies) else 0
