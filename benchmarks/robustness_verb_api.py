"""Verb promises: the Python API's argument types (generated wrong values for the options classes)
and the honest states (``bundle verify`` claims, learning-time intervals, ``scene show`` answering as
``run``)."""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

from .harness.cases import (
    Outcome,
    Verdict,
    default_bundle_dir,
    run_cli,
    toml_text,
    with_timeout,
    worst,
)
from .reference_configs import int8_bundle_path
from .robustness_inputs import guarded

# ================================================================== shared inputs
from .robustness_verb_base import UNSET_VAR, Case, Cases, Inputs, drawn


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
    int8 = int8_bundle_path()
    claims: list[tuple[Path, str, tuple[str, ...], Any]] = [(default, "the shipped default bundle", (), None),
                                                            (int8, "the shipped int8 RGBmod", (), None)]
    claims += [(default, "default (fp32)", ("precision",), p) for p in ("int8-static", "int8-dynamic", "fp16")]
    claims += [(int8, "int8 RGBmod (int8-static)", ("precision",), p) for p in ("int8-dynamic", "fp16", "fp32")]
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
