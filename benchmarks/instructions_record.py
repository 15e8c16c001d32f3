"""The instructions benchmark's record (instructions.json) and its page (instructions.md): what
benchmarks/instructions.py counted, per shipped bundle and per-frame path, the goals, the floors and
the before / after tables; an earlier record read back as the page's "before"."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from .harness import callgrind

#: Shipped bundles measured: (folder under edge/models, label). The labels name the graph, as the
#: goals and earlier records do: "RGBmod" the int8 RGBmod (the default until the fp32 "RGBmod
#: fast" took its place: docs/benchmarks/default_bundle.md).
VARIANTS: tuple[tuple[str, str], ...] = (("rgbmod_int8", "RGBmod"), ("d", "D"), ("rgbmod_d", "RGBmod+D"),
                                         ("default", "RGBmod fast"))


# ----------------------------------------------------------------------------- the record
@dataclass
class Count:
    """Instructions per reading / call of one mode: total and per group
    (:data:`~.harness.callgrind.GROUP_NAMES`)."""

    total: float
    groups: dict[str, float]


@dataclass
class VariantCounts:
    """One bundle's counts: mode -> :class:`Count` (runtime, bare, gate, depth where it has
    one) and the ratio runtime / bare."""

    bundle: str
    label: str
    counts: dict[str, Count]
    ratio: float
    #: the per-frame path counted (:data:`PATHS`); records before the robot-side path existed: compiled
    path: str = "compiled"


@dataclass
class Record:
    """instructions.json: what was counted, how, where."""

    command: str
    commit: str
    cpu: str
    machine: str
    readings: int
    frames: int
    warmup: int
    valgrind: str
    variants: list[VariantCounts] = field(default_factory=list)
    seconds: float = 0.0
    before_commit: str = ""
    before: list = field(default_factory=list)  # the before record's variants, as in its JSON
    notes: str = ""  # what the page says besides (e.g. counts carried over from another run)


# ----------------------------------------------------------------------------- the page
#: The goals (issue's wording in docs): runtime / bare graph per bundle, at most.
GOALS = {"RGBmod": 1.15, "D": 1.5, "RGBmod+D": 1.25}
#: The fast RGBmod's goal (the default bundle): its reading / the int8 RGBmod's reading, at most.
FAST_GOAL = 0.5


def _m(x: float) -> str:
    return f"{x / 1e6:.3f}"


def stages(v: VariantCounts) -> dict[str, float]:
    """Instructions per reading by stage: runtime, bare, gate, depth, and the rest (glue +
    judge + the model wrapper = runtime - bare - gate - depth); a stage not counted is absent."""
    c = v.counts
    out = {"runtime": c["runtime"].total, "bare": c["bare"].total}
    for k in ("gate", "depth"):
        if k in c:
            out[k] = c[k].total
    if "gate" in c:
        out["glue + judge"] = out["runtime"] - out["bare"] - out["gate"] - out.get("depth", 0.0)
    return out


def _variants(raw: list) -> list[VariantCounts]:
    return [VariantCounts(v["bundle"], v["label"], {k: Count(**c) for k, c in v["counts"].items()}, v["ratio"],
                          v.get("path", "compiled")) for v in raw]


def _paths_section(rec: Record) -> list[str]:
    """Per bundle: the robot-side path's reading against the compiled kernels' (and against the before
    record's, counted on the compiled kernels where it predates the robot-side path)."""
    from .harness.stats import markdown_table

    by = {(v.bundle, v.path): v for v in rec.variants}
    before = {v.bundle: v for v in _variants(rec.before) if v.path == "compiled"} if rec.before else {}
    rows = []
    for name, label in VARIANTS:
        c, o = by.get((name, "compiled")), by.get((name, "opencv"))
        if o is None:
            continue
        oc = o.counts["runtime"].total
        cc = c.counts["runtime"].total if c else None
        b = before.get(name)
        bc = b.counts["runtime"].total if b else None
        rows.append([label, _m(oc), "-" if cc is None else _m(cc),
                     "-" if cc is None else f"{100 * (oc / cc - 1):+.0f} %",
                     "-" if bc is None else _m(bc), "-" if bc is None else f"{100 * (oc / bc - 1):+.0f} %",
                     "-" if cc is None or bc is None else f"{100 * (cc / bc - 1):+.1f} %"])
    if not rows:
        return []
    return ["## The robot-side path against the compiled kernels (M per reading)", "",
            "The robot-side install (`pip install .`) runs the gate's and the depth stage's OpenCV / numpy calls; "
            "the `fast` extra the compiled kernels (edge/compiled_path.py). The readings are the same; the "
            "instructions are not. 'before': the before record's reading (compiled kernels)." if rec.before else
            "The robot-side install (`pip install .`) runs the gate's and the depth stage's OpenCV / numpy calls; "
            "the `fast` extra the compiled kernels (edge/compiled_path.py). The readings are the same.", "",
            markdown_table(["bundle", "robot-side path", "compiled kernels", "robot-side / compiled", "before",
                            "robot-side / before", "compiled / before"], rows), ""]


def _fast_ratio(variants: list[VariantCounts]) -> float | None:
    """The fast RGBmod's runtime reading / the int8 RGBmod's (None unless both were counted)."""
    by = {v.label: v for v in variants}
    if "RGBmod fast" not in by or "RGBmod" not in by:
        return None
    return by["RGBmod fast"].counts["runtime"].total / by["RGBmod"].counts["runtime"].total


def _floors(rec: Record) -> list[str]:
    """The page's floors section: per bundle with a goal, what the goal leaves around the bare call
    against what the reading does there that no exact implementation of today's checks avoids."""
    from .harness.stats import markdown_table

    rows = []
    for v in rec.variants:
        c, st = v.counts, stages(v)
        if v.label not in GOALS or "downscale" not in c or "gate" not in st:
            continue
        budget = (GOALS[v.label] - 1.0) * st["bare"]
        down = c["downscale"].total
        left = budget - down - st["glue + judge"]
        rest = st["gate"] - down + st.get("depth", 0.0)
        cv = f" (OpenCV's x2 steps: {_m(c['downscale_opencv'].total)})" if "downscale_opencv" in c else ""
        rows.append([v.label, f"{GOALS[v.label]:.2f}x", _m(budget), _m(down) + cv, _m(st["glue + judge"]),
                     _m(left), _m(rest), f"{rest / left:.1f}x" if left > 0 else "no room"])
    if not rows:
        return []
    return ["## What a goal leaves for the checks (M per reading)", "",
            "'room around the bare call': (goal - 1) x the bare call. 'the one downscale': the gate's reduction of "
            "the frame alone, which the network's input is, bit for bit (the gate's kernel; OpenCV's INTER_AREA x2 "
            "steps give the same values for the count in brackets). 'left for the checks': the room less the "
            "downscale and the runtime's glue + judge. 'the checks cost': the gate step beyond its downscale (frame "
            "contract, exposure, blur, thumbnail, pixel noise, photometric fit, changed mask, blobs, judging) and the "
            "depth stage. Every check is one compiled pass or OpenCV call per frame; the goal holds only where "
            "'checks / left' is at most 1.", "",
            markdown_table(["bundle", "goal", "room around the bare call", "the one downscale", "glue + judge",
                            "left for the checks", "the checks cost", "checks / left"], rows), ""]


def page(rec: Record) -> str:
    """instructions.md from the record (with before / after tables when it holds a before)."""
    from .harness.stats import markdown_table

    before = {v.label: v for v in _variants(rec.before)} if rec.before else {}
    out = ["# Instructions per reading", "", f"Command: `{rec.command}`", "", f"Commit: {rec.commit}", "",
           f"CPU: {rec.cpu}. Machine: {rec.machine}.", "",
           f"Counted by {rec.valgrind} (callgrind: instructions executed, the same on any load or clock). Per "
           f"shipped bundle, {rec.readings} readings back to back over {rec.frames} virtual DIGIT frames in contact, "
           f"after {rec.warmup} warm-up readings, each stage counted alone in the bundle's one run "
           "(benchmarks/instructions.py). 'runtime': one `ForceRuntime.step` (one sensor, in-memory source, "
           "warm-ups off); 'bare': one `InferenceSession.run` of the bundle's graph (one thread) on the same reduced "
           "inputs; 'gate': the gate step alone (frame contract, exposure, contact gate); 'depth': the depth stage "
           "alone on the gate's reduced image and mask; 'glue + judge': runtime - bare - gate - depth (the "
           "runtime's own work, the judge, the model wrapper). M = millions of instructions per reading.", ""]
    if rec.notes:
        out += [rec.notes, ""]
    if before:
        out += [f"Before: commit {rec.before_commit} (the same command and CPU).", "", "## Goals", ""]
        rows = []
        for v in rec.variants:
            b = before.get(v.label)
            if v.label in GOALS:
                rows.append([f"{v.label}: runtime / bare graph <= {GOALS[v.label]:.2f}x",
                             f"{b.ratio:.2f}x" if b else "-", f"{v.ratio:.2f}x",
                             "met" if v.ratio <= GOALS[v.label] else "NOT met"])
        fast = _fast_ratio(rec.variants)
        if fast is not None:
            b_fast = _fast_ratio(_variants(rec.before))
            rows.append([f"RGBmod fast: its reading / the int8 RGBmod's reading <= {FAST_GOAL:.2f}x",
                         f"{b_fast:.2f}x" if b_fast is not None else "-", f"{fast:.2f}x",
                         "met" if fast <= FAST_GOAL else "NOT met"])
        out += [markdown_table(["goal", "before", "after", ""], rows), ""]
    rows = []
    for v in rec.variants:
        st = stages(v)
        rows.append([v.label, _m(st["runtime"]), _m(st["bare"]), f"{v.ratio:.2f}x",
                     *(_m(st[k]) if k in st else "-" for k in ("gate", "depth", "glue + judge"))])
    out += ["## Per reading", "",
            markdown_table(["bundle", "runtime (M)", "bare call (M)", "runtime / bare", "gate (M)", "depth (M)",
                            "glue + judge (M)"], rows), ""]
    if before:
        rows = []
        for v in rec.variants:
            b = before.get(v.label)
            if b is None:
                continue
            sa, sb = stages(v), stages(b)
            for k in sa:
                if k in sb:
                    rows.append([v.label, k, _m(sb[k]), _m(sa[k]), _m(sa[k] - sb[k]),
                                 f"{100 * (sa[k] / sb[k] - 1):+.0f} %" if sb[k] else "-"])
        out += ["## Per stage, before and after (M per reading)", "",
                markdown_table(["bundle", "stage", "before", "after", "change", "change %"], rows), ""]
    out += _paths_section(rec)
    out += _floors(rec)
    groups = callgrind.GROUP_NAMES
    out += ["## Where the instructions ran (M per reading)", "",
            "By object file (OpenCV: cv2 and libopencv*; numpy: its extension modules; the interpreter: "
            "python / libpython; libc memset/memcpy: those functions of the C library, the rest of it apart).", ""]
    rows = []
    for v in rec.variants:
        b = before.get(v.label)
        for mode, cnt in v.counts.items():
            if b is not None and mode in b.counts:
                bc = b.counts[mode]
                rows.append([v.label, f"{mode} (before)", _m(bc.total), *(_m(bc.groups[g]) for g in groups)])
            rows.append([v.label, mode if b is None else f"{mode} (after)", _m(cnt.total),
                         *(_m(cnt.groups[g]) for g in groups)])
    out += [markdown_table(["bundle", "what", "total", *groups], rows), ""]
    out += [f"Each bundle's modes counted in one run, each alone (callgrind's client requests; set-up and "
            f"imports neither instrumented nor counted). Counting took {rec.seconds:.0f} s.", ""]
    return "\n".join(out) + "\n"


def read_before(path: Path) -> tuple[str, list]:
    """(commit, variants as in the JSON) of an earlier instructions.json; ValueError saying what is
    wrong (missing, a folder, not JSON, a key or a variant's field missing or of the wrong type)."""
    path = Path(path)
    if not path.exists():
        raise ValueError("no such file; expected an earlier instructions.json")
    if not path.is_file():
        raise ValueError("not a file; expected an earlier instructions.json")
    try:
        raw = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"not readable as JSON ({exc.__class__.__name__}: {exc})") from None
    if not isinstance(raw, dict) or not isinstance(raw.get("commit"), str) or not isinstance(raw.get("variants"),
                                                                                           list):
        raise ValueError("expected an instructions.json: an object with 'commit' (text) and 'variants' (a list)")
    try:
        parsed = _variants(raw["variants"])
        for v in parsed:
            stages(v)
            float(v.ratio)
            for c in v.counts.values():
                float(c.total)
                {str(k): float(x) for k, x in c.groups.items()}
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ValueError(f"a variant is not of the shape instructions.json records ({exc.__class__.__name__}: "
                         f"{exc})") from None
    return raw["commit"], raw["variants"]
