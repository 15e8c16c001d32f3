"""Robustness categories of what enters the package: frames and exposure, bundle manifests, scene
files, checkpoint metadata and CLI arguments, each case probed through the public API or the CLI
(benchmarks/robustness.py runs them)."""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st

from .harness.cases import (
    Outcome,
    Verdict,
    accepted,
    cli_verdict,
    default_bundle_dir,
    make_dataset,
    refusal,
    run_cli,
    toml_text,
    worst,
    write_frame_png,
)
from .robustness_table import fill, rows, section, set_at, values

# =============================================================================== frames
_SHAPES = [tuple(shape) for shape in values("frame_shapes")]
_DTYPES = [np.uint8, np.float32, np.float64, np.int16, np.uint16, np.bool_]


@st.composite
def frame_inputs(draw) -> Any:
    kind = draw(st.sampled_from(["array", "array", "array", "other"]))
    if kind == "other":
        return draw(st.sampled_from([None, [1, 2, 3], "frame.png", 3.0, {"rgb": 1}]))
    shape = draw(st.sampled_from(_SHAPES))
    dtype = draw(st.sampled_from(_DTYPES))
    fill = draw(st.sampled_from([0, 1, 128, 255, "nan", "random"]))
    if fill == "random":
        x = np.random.default_rng(draw(st.integers(0, 2**16))).integers(0, 256, shape).astype(dtype)
    elif fill == "nan":
        x = np.full(shape, np.nan if np.issubdtype(dtype, np.floating) else 7, dtype=dtype)
    else:
        x = np.full(shape, fill, dtype=dtype)
    return x


def probe_frame(x: Any) -> Verdict:
    from tactile_force.edge.frames import check_frame

    ok = isinstance(x, np.ndarray) and x.dtype == np.uint8 and x.shape == (320, 240, 3)
    try:
        out = check_frame(x, name="probe frame")
    except BaseException as exc:  # noqa: BLE001
        return refusal(exc, not ok, names=("probe frame",))
    if ok and out is not x and not np.array_equal(out, x):
        return Verdict(Outcome.SILENT_WRONG, "check_frame changed the frame")
    return accepted(not ok, f"{getattr(x, 'shape', type(x).__name__)} {getattr(x, 'dtype', '')}")


@st.composite
def exposure_patterns(draw) -> np.ndarray:
    """Fine periodic patterns (checkerboards, stripes) that fool a strided sample."""
    period = draw(st.integers(1, 8))
    phase_r, phase_c = draw(st.integers(0, 7)), draw(st.integers(0, 7))
    lo, hi = draw(st.sampled_from([(0, 255), (0, 250), (5, 255), (0, 128)]))
    kind = draw(st.sampled_from(["checker", "rows", "cols"]))
    r, c = np.indices((320, 240))
    if kind == "checker":
        on = ((r + phase_r) // period + (c + phase_c) // period) % 2 == 0
    elif kind == "rows":
        on = ((r + phase_r) // period) % 2 == 0
    else:
        on = ((c + phase_c) // period) % 2 == 0
    img = np.where(on[..., None], hi, lo).astype(np.uint8)
    return np.repeat(img, 3, axis=2) if img.shape[2] == 1 else img


def probe_exposure(frame: np.ndarray) -> Verdict:
    """exposure_problem must judge the whole frame: its all-dark / all-white verdict has to
    match the frame's true mean (a sample that reads a checkerboard as white is silent wrong)."""
    from tactile_force.edge.frames import DARK_LEVEL, WHITE_LEVEL, exposure_problem

    mean = float(frame.mean())
    truth = "all-dark" if mean < DARK_LEVEL else "all-white" if mean > WHITE_LEVEL else None
    got = exposure_problem(frame)
    if got in ("all-dark", "all-white") or truth is not None:
        if got != truth:
            return Verdict(Outcome.SILENT_WRONG, f"mean {mean:.1f}: exposure_problem says {got}, expected {truth}")
    return Verdict(Outcome.ACCEPTED if got is None else Outcome.CLEAR, f"mean {mean:.1f}: {got}")


# =============================================================================== manifests
def _paths(obj: Any, prefix: tuple = ()) -> Iterator[tuple]:
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, (*prefix, i))


@functools.lru_cache(maxsize=1)
def _base_manifest_text() -> str:
    return (default_bundle_dir() / "model.json").read_text()


def base_manifest() -> dict:
    """A fresh copy of the default bundle's manifest (read once)."""
    return json.loads(_base_manifest_text())


def manifest_paths() -> list[tuple]:
    return [p for p in _paths(base_manifest()) if p]
#: top-level fields a changed value of which must make loading fail (hash, graph contract, file)
_MUST_MATCH = {"sha256", "variant", "onnx_file", "inputs", "output", "format_version"}

json_values = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-2**40, 2**40), st.floats(allow_nan=False, allow_infinity=False),
              st.text(max_size=12), st.sampled_from(["d", "rgbmod+d", "fp32", "../../x/model.onnx", "/etc/passwd",
                                                      "model.onnx", "NaN", "abc", ""])),
    lambda children: st.one_of(st.lists(children, max_size=3), st.dictionaries(st.text(max_size=6), children,
                                                                              max_size=3)),
    max_leaves=6)


@st.composite
def manifest_mutations(draw) -> tuple[str, Any]:
    """(description, manifest object): the default bundle's manifest with one field deleted or
    replaced, or an arbitrary JSON value instead of the whole manifest."""
    op = draw(st.sampled_from(["replace", "replace", "replace", "delete", "whole"]))
    if op == "whole":
        return "whole manifest replaced", draw(json_values)
    m = base_manifest()
    path = draw(st.sampled_from(manifest_paths()))
    parent = m
    for k in path[:-1]:
        parent = parent[k]
    old = parent[path[-1]]
    if op == "delete":
        if isinstance(parent, list):
            parent.pop(path[-1])
        else:
            del parent[path[-1]]
        return f"deleted {'.'.join(map(str, path))}", m
    new = draw(json_values)
    parent[path[-1]] = new
    changed = json.dumps(new, sort_keys=True) != json.dumps(old, sort_keys=True)
    tag = "MUST-REFUSE " if changed and path[0] in _MUST_MATCH else ""
    return f"{tag}{'.'.join(map(str, path))} = {json.dumps(new)[:60]}", m


def targeted_manifests() -> list[tuple[str, Any]]:
    """The hand-picked manifests (robustness_cases.toml ``[[manifest_lie]]``, each must be
    refused; ``[manifest_partial]`` records cut to their first key)."""
    out: list[tuple[str, Any]] = []
    for row in rows("manifest_lie"):
        m = base_manifest()
        value = fill(row["value"], {"bundle": default_bundle_dir()})
        set_at(m, row["path"], value)
        out.append((f"MUST-REFUSE {'.'.join(map(str, row['path']))} = {json.dumps(value)}", m))
    for key in section("manifest_partial")["keys"]:
        m = base_manifest()
        if isinstance(m.get(key), dict) and m[key]:
            first = next(iter(m[key]))
            m[key] = {first: m[key][first]}
            out.append((f"partial {key}", m))
    return out


def probe_manifest(folder: Path, case: tuple[str, Any], *, cli: bool = False) -> Verdict:
    """Write ``case``'s manifest beside the default bundle's graph and load it with load_bundle
    (and, for a manifest that does not fit the graph, open it with OnnxForceModel as the
    runtime does); with ``cli``, also run ``tactile-force bundle verify`` and ``bundle show``."""
    from tactile_force.edge import load_bundle

    what, manifest = case
    must_refuse = what.startswith("MUST-REFUSE")
    (folder / "model.json").write_text(json.dumps(manifest))
    try:
        bundle = load_bundle(folder)
        if must_refuse:  # the runtime's entry must refuse it when the reader did not
            from tactile_force.edge.model.onnx_model import OnnxForceModel

            OnnxForceModel(bundle, warmup=0)
        v = accepted(True if must_refuse else None, what)
    except BaseException as exc:  # noqa: BLE001
        v = refusal(exc, True if must_refuse else None)
    if not cli:
        return Verdict(v.outcome, f"{what}: {v.detail}")
    verdicts = [v, cli_verdict(["bundle", "verify", str(folder)], {0, 1, 2}, must_refuse)]
    rc, out, err = run_cli(["bundle", "show", str(folder)])
    if "Traceback" in out + err or rc not in (0, 1, 2):
        verdicts.append(Verdict(Outcome.TRACEBACK, f"bundle show exit {rc}: {err[-200:]}"))
    w = worst(verdicts)
    return Verdict(w.outcome, f"{what}: {w.detail}")


# =============================================================================== scenes


def base_scene(folder: Path) -> dict:
    """A valid replay scene over a small dataset in ``folder`` (no shared data needed)."""
    data = folder / "replay"
    if not data.is_dir():
        make_dataset(data, n=3)
    return {"runtime": {"bundle": "default", "backend": "cpu", "deadline_ms": 16.7, "threads": 1},
            "gate": {"threshold": 12, "background_frames": 5},
            "sensor": [{"name": "digit", "source": "replay", "path": "replay", "fps": 60.0}],
            "output": [{"kind": "stdout"}, {"kind": "csv", "path": str(folder / "out" / "readings.csv")}]}


toml_values = st.one_of(st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True, allow_infinity=True),
                        st.text(max_size=10), st.sampled_from(["high", "5", "replay", "camera", "/nonexistent",
                                                               "default", ""]),
                        st.lists(st.integers(0, 9), max_size=3), st.dictionaries(st.text("abc", max_size=3),
                                                                                 st.integers(0, 9), max_size=2))


@st.composite
def scene_mutations(draw, folder_marker: str = "") -> tuple[str, Callable[[dict], dict]]:
    """(description, function that mutates a base scene) for one key replaced/deleted/added."""
    section = draw(st.sampled_from(["runtime", "gate", "sensor", "output", "top"]))
    op = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
    value = draw(toml_values)
    keys = {"runtime": ["bundle", "backend", "deadline_ms", "threads"], "gate": ["threshold", "background_frames"],
            "sensor": ["name", "source", "path", "fps"], "output": ["kind", "path"], "top": ["runtime", "sensor"]}
    key = draw(st.sampled_from(keys[section] + ["n_grasps", "unknown_key"]))

    def mutate(scene: dict) -> dict:
        s = json.loads(json.dumps(scene))
        table = s if section == "top" else (s[section][-1] if isinstance(s.get(section), list) else s[section])
        if op == "delete":
            table.pop(key, None)
        else:
            table[key] = value
        return s

    return f"{section}.{key} {op} {value!r}"[:80], mutate


def probe_scene(folder: Path, case: tuple[str, Callable[[dict], dict]]) -> Verdict:
    from tactile_force.edge import load_scene

    what, mutate = case
    scene = mutate(base_scene(folder))
    path = folder / "scene.toml"
    try:
        path.write_text(toml_text(scene))
    except (TypeError, ValueError):
        return Verdict(Outcome.ACCEPTED, f"{what}: not expressible in TOML")
    try:
        load_scene(path)
        return Verdict(Outcome.ACCEPTED, what)
    except BaseException as exc:  # noqa: BLE001
        v = refusal(exc, None)
        return Verdict(v.outcome, f"{what}: {v.detail}")


def targeted_scenes() -> list[tuple[str, Callable[[dict], dict], bool]]:
    """The hand-picked scenes (robustness_cases.toml ``[[scene_edit]]``): (what, mutation, must_refuse)."""

    def edit(row: dict[str, Any]) -> Callable[[dict], dict]:
        def f(scene: dict) -> dict:
            s = json.loads(json.dumps(scene))
            if "section" not in row:
                return s
            if row["section"] == "top":
                s[row["key"]] = row["value"]
            else:
                sec = s[row["section"]]
                t = sec[0] if isinstance(sec, list) else s.setdefault(row["section"], {})
                t[row["key"]] = row["value"]
            return s
        return f

    return [(row["what"], edit(row), bool(row["refuse"])) for row in rows("scene_edit")]


# =============================================================================== checkpoint metadata
_META_VALUES = st.one_of(st.none(), st.booleans(), st.integers(-10, 10), st.floats(allow_nan=True, allow_infinity=True),
                         st.sampled_from(["abc", "rgbmod", "d", "dmod", "rgbmod+d", "RGBMOD", "", "0.25"]),
                         st.lists(st.integers(0, 3), max_size=2), st.sampled_from(["TENSOR", "NESTED_TENSOR"]))


@st.composite
def checkpoint_metas(draw) -> Any:
    if draw(st.integers(0, 9)) == 0:
        return draw(st.sampled_from([[1, 2], "rgbmod", 3, "TENSOR", [], (1,)]))
    keys = draw(st.lists(st.sampled_from(["variant", "width", "input_scale", "note", "trained_on", "epochs", 7]),
                         max_size=4, unique=True))
    return {k: draw(_META_VALUES) for k in keys}


def _materialise(v: Any) -> Any:
    import torch

    if v == "TENSOR":
        return torch.zeros(2)
    if v == "NESTED_TENSOR":
        return [torch.zeros(1)]
    if isinstance(v, dict):
        return {k: _materialise(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_materialise(x) for x in v]
    return v


def expected_meta_ok(meta: Any) -> bool:
    """The documented rule: None or a dict with text keys; variant a known variant name;
    width a number in (0, 4]; input_scale a number in (0, 1]; every value plain data."""
    if meta is None:
        return True
    if not isinstance(meta, dict) or any(not isinstance(k, str) for k in meta):
        return False

    def plain(v: Any) -> bool:
        if v in ("TENSOR", "NESTED_TENSOR"):
            return False
        if isinstance(v, float):
            return math.isfinite(v)
        if isinstance(v, list):
            return all(plain(x) for x in v)
        return v is None or isinstance(v, (str, int, bool))

    if not all(plain(v) for v in meta.values()):
        return False
    if "variant" in meta and not (isinstance(meta["variant"], str)
                                  and meta["variant"].strip().lower() in ("rgbmod", "d", "dmod", "rgbmod+d")):
        return False
    for key, hi in (("width", 4.0), ("input_scale", 1.0)):
        if key in meta:
            v = meta[key]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v <= hi:
                return False
    return True


def probe_checkpoint_meta(folder: Path, meta: Any) -> Verdict:
    import torch
    from tactile_force.export.checkpoint import load_checkpoint, resolve_spec

    ok = expected_meta_ok(meta)
    path = folder / "ckpt.pth"
    torch.save({"state_dict": {"conv1.weight": torch.zeros(1)}, "tactile_force": _materialise(meta)}, path)
    try:
        ckpt = load_checkpoint(path)
    except BaseException as exc:  # noqa: BLE001
        v = refusal(exc, not ok, names=("ckpt.pth",))
        return Verdict(v.outcome, f"{meta!r}: {v.detail}"[:300])
    if not ok:
        return Verdict(Outcome.SILENT_WRONG, f"accepted metadata {meta!r}"[:300])
    try:
        resolve_spec(ckpt)
    except BaseException as exc:  # noqa: BLE001
        v = refusal(exc, None)  # no variant: a clear "pass --variant" is right
        if v.outcome is not Outcome.CLEAR:
            return Verdict(v.outcome, f"{meta!r}: resolve_spec: {v.detail}"[:300])
    return Verdict(Outcome.ACCEPTED, repr(meta)[:200])


# =============================================================================== CLI arguments
def cli_cases(folder: Path) -> list[tuple[list[str], set[int], tuple[str, ...]]]:
    """(argv, allowed exit codes, words the message must contain) of bad arguments
    (robustness_cases.toml ``[[cli_argument]]``): all exit 2."""
    afile = folder / "a_file.txt"
    afile.write_text("x")
    places = {"folder": folder, "afile": afile, "bundle": default_bundle_dir()}
    return [(fill(row["argv"], places), {2}, tuple(fill(row["names"], places))) for row in rows("cli_argument")]


def calib_channel_cases(folder: Path) -> list[tuple[str, str, Path]]:
    """(what, variant, folder of PNGs) that quantize --calib must refuse: colour for depth, grey for RGB."""
    import cv2

    colour, grey = folder / "colour_pngs", folder / "grey_pngs"
    for d in (colour, grey):
        d.mkdir(exist_ok=True)
    for i in range(3):
        write_frame_png(colour / f"{i}.png", i)
        cv2.imwrite(str(grey / f"{i}.png"), np.full((320, 240), 80 + i, np.uint8))
    return [("colour PNGs for a D bundle", "d", colour), ("colour PNGs for a Dmod bundle", "dmod", colour),
            ("grey PNGs for an RGBmod bundle", "rgbmod", grey)]


def probe_calib_channels(variant: str, path: Path) -> Verdict:
    from tactile_force.export.calibration import CalibrationData

    try:
        d = CalibrationData.from_path(path, variant, min_frames=1)
    except BaseException as exc:  # noqa: BLE001
        return refusal(exc, True, names=(".png", "channel"))
    return Verdict(Outcome.SILENT_WRONG, f"calibrated {variant} on {path.name}: {[v.shape for v in d.inputs.values()]}")
