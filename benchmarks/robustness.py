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

import contextlib
import functools
import json
import logging
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
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

REPO = require_repo("the robustness suite (its workers are in tests/robustness)")
KILL_WORKER = REPO / "tests" / "robustness" / "record_kill_worker.py"
DOCS = REPO / "docs" / "robustness.md"
MAX_FORCE_N = 200.0


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


# =============================================================================== labels
_LABEL_TOKENS = [b"", b"\n", b"   \n", b"nan", b"NaN\n", b"inf", b"-inf", b"-5", b"-5.0\n", b"1e308", b"-0.0",
                 b"0", b"0.0\n", b"200", b"200.0001", b"1_000", b"0x10", b"\xef\xbb\xbf3.5\n", b"\xff\xfe3\n",
                 b"3.5,2.0\n", b"abc\n", b"\x00\x00", b"1.0813515186309814\n0.0173\n0.0175\n", b"  \n 4.2 \n",
                 b"1e-3", b".5", b"5.", b"+4", b"4 N", b"\xe9\n", b"12\x00\n", b"1e400", b"infinity",
                 b"1,08\n", b"0,95\n", b"1.08 N\n", b"1.08N\n", b"108 g\n", b"3.5; 2.0\n", b"3.5 2.0\n",
                 b"12,5 N\n", b"1.5 # scale\n"]


def label_bytes() -> st.SearchStrategy[bytes]:
    """Contents of a force_N.txt: valid forces, odd numbers, odd tokens, junk and text."""
    good = st.floats(0.0, MAX_FORCE_N, allow_nan=False).map(lambda v: f"{v!r}\n".encode())
    numbers = st.floats(allow_nan=True, allow_infinity=True).map(lambda v: repr(v).encode())
    tokens = st.sampled_from(_LABEL_TOKENS)
    junk = st.binary(max_size=24)
    text = st.text(max_size=12).map(lambda s: s.encode("utf-8", "surrogatepass"))
    tail = st.tuples(st.one_of(tokens, good), st.one_of(junk, text)).map(lambda t: t[0] + b"\n" + t[1])
    return st.one_of(good, numbers, tokens, junk, text, tail)


def expected_label(data: bytes) -> float | None:
    """The label's force by the documented rule (docs/robustness.md), or None when invalid."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return None
    if "\x00" in text:
        return None
    first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
    if re.match(r"[+-]?\d+,\d", first):  # a decimal comma: 1,08
        return None
    fields = [f for f in re.split(r"\s*[,;]\s*|\s+", first) if f]
    if not fields:
        return None
    values = []
    for f in fields:  # the force, then only numbers (no unit, no text)
        if set(f) - set("0123456789.eE+-"):
            return None
        try:
            values.append(float(f))
        except ValueError:
            return None
    v = values[0]
    return v if math.isfinite(v) and 0.0 <= v <= MAX_FORCE_N else None


class _Count(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def probe_label(root: Path, data: bytes, *, calib: bool = True) -> Verdict:
    """One label file through every reader: read_force_file, the dataset reader, the replay
    source (must warn once and yield truth None, never die) and quantize's --calib reader."""
    from tactile_force.edge.data.dataset import AuthorsDataset, read_force_file
    from tactile_force.edge.sources import ReplayFolderSource

    want = expected_label(data)
    bad = want is None
    label = root / "forces" / "force_0.txt"
    label.write_bytes(data)
    names = ("force_0.txt",)
    verdicts: list[Verdict] = []

    def value_check(v: float, who: str) -> Verdict:
        if bad:
            return accepted(True, f"{who} read {v!r} from {data[:30]!r}")
        if v != want:
            return Verdict(Outcome.SILENT_WRONG, f"{who} read {v!r}, the file says {want!r}")
        return Verdict(Outcome.ACCEPTED)

    for who, read in (("read_force_file", lambda: read_force_file(label)),
                      ("AuthorsDataset", lambda: AuthorsDataset(root).load(0).force_n)):
        try:
            verdicts.append(value_check(read(), who))
        except BaseException as exc:  # noqa: BLE001
            verdicts.append(refusal(exc, bad, names=names))
    # replay: never dies on a bad label; warns once per file; truth None
    log = logging.getLogger("tactile_force.edge.sources.files")
    h = _Count()
    log.addHandler(h)
    try:
        src = ReplayFolderSource(root, fps=None)
        frames = [src.read(), src.read()]
        src.close()
        if frames[0] is None:
            verdicts.append(Verdict(Outcome.SILENT_WRONG, "replay yielded no frame"))
        else:
            tf = frames[0]
            if bad:
                warned = [r for r in h.records if "force_0.txt" in r.getMessage()]
                if tf.truth_n is not None:
                    verdicts.append(Verdict(Outcome.SILENT_WRONG, f"replay truth {tf.truth_n!r} from a bad label"))
                elif len(warned) != 1 or "label_error" not in tf.meta:
                    verdicts.append(Verdict(Outcome.SILENT_WRONG, f"replay: {len(warned)} warnings, meta {tf.meta}"))
                else:
                    verdicts.append(Verdict(Outcome.CLEAR, warned[0].getMessage()[:200]))
            else:
                verdicts.append(value_check(tf.truth_n, "replay"))
    except BaseException as exc:  # noqa: BLE001
        verdicts.append(Verdict(Outcome.TRACEBACK, f"replay died: {type(exc).__name__}: {exc}"[:300]))
    finally:
        log.removeHandler(h)
    if calib:
        from tactile_force.export.calibration import CalibrationData

        try:
            forces = CalibrationData.from_path(root, "rgbmod", min_frames=1).forces
            verdicts.append(value_check(float(forces[0]), "quantize --calib"))
        except BaseException as exc:  # noqa: BLE001
            verdicts.append(refusal(exc, bad, names=names))
    return worst(verdicts)


# =============================================================================== meta.jsonl
@st.composite
def meta_bytes(draw) -> bytes:
    """A meta.jsonl: valid records, then maybe cut short, binary junk or a non-object line."""
    n = draw(st.integers(1, 4))
    lines = [json.dumps({"id": i, "timestamp_ns": draw(st.integers(0, 2**62))}).encode() + b"\n" for i in range(n)]
    data = b"".join(lines)
    op = draw(st.sampled_from(["none", "truncate", "junk", "line", "binary"]))
    if op == "truncate":
        data = data[:draw(st.integers(0, len(data)))]
    elif op == "junk":
        data += draw(st.binary(min_size=1, max_size=16))
    elif op == "line":
        bad = draw(st.sampled_from([b"[1, 2]", b"42", b'"id"', b'{"id": "3"}', b'{"id": -1}', b'{"id": true}',
                                    b'{"noid": 1}', b"{", b"null"]))
        k = draw(st.integers(0, n))
        parts = data.split(b"\n")
        parts.insert(k, bad)
        data = b"\n".join(parts)
    elif op == "binary":
        data = draw(st.binary(min_size=1, max_size=40))
    return data


def expected_meta(data: bytes) -> int | None:
    """None when every non-blank line is a JSON object with an integer id >= 0, else the
    1-based number of the first bad line."""
    for k, raw in enumerate(data.split(b"\n"), start=1):
        if not raw.strip():
            continue
        try:
            rec = json.loads(raw.decode("utf-8"))
        except ValueError:
            return k
        n = rec.get("id") if isinstance(rec, dict) else None
        if not isinstance(n, int) or isinstance(n, bool) or n < 0:
            return k
    return None


def probe_meta(root: Path, data: bytes) -> Verdict:
    from tactile_force.edge.data.dataset import AuthorsDataset

    (root / "meta.jsonl").write_bytes(data)
    bad_line = expected_meta(data)
    try:
        ds = AuthorsDataset(root)
    except BaseException as exc:  # noqa: BLE001
        return refusal(exc, bad_line is not None, names=("meta.jsonl", f"line {bad_line}") if bad_line else ())
    return accepted(bad_line is not None, f"meta ids {sorted(ds.meta)}")


# =============================================================================== frames
_SHAPES = [(320, 240, 3), (240, 320, 3), (320, 240), (320, 240, 4), (1, 320, 240, 3), (0, 240, 3), (320, 240, 1),
           (320, 241, 3), (3,), ()]
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


#: hand-picked manifests that crashed at commit 9ed225d (a matching hash and a graph that does not fit)
def targeted_manifests() -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    for path, value in ((("variant",), "d"), (("variant",), "rgbmod+d"), (("onnx_file",), "../../x/model.onnx"),
                        (("onnx_file",), "/etc/hostname"), (("onnx_file",), str(default_bundle_dir() / "model.onnx")),
                        (("inputs", 0, "shape"), [1, 320, 240, 3]), (("inputs", 0, "dtype"), "float32"),
                        (("inputs", 0, "name"), "depth"), (("output", "name"), "force"),
                        (("sha256",), "0" * 64), (("format_version",), 99)):
        m = base_manifest()
        parent = m
        for k in path[:-1]:
            parent = parent[k]
        parent[path[-1]] = value
        out.append((f"MUST-REFUSE {'.'.join(map(str, path))} = {json.dumps(value)}", m))
    for key in ("parity", "error", "architecture", "quantization", "provenance"):
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
    """The scenes that crashed at commit 9ed225d: (what, mutation, must_refuse)."""

    def setter(section: str, key: str, value: Any) -> Callable[[dict], dict]:
        def f(scene: dict) -> dict:
            s = json.loads(json.dumps(scene))
            if section == "top":
                s[key] = value
            else:
                t = s[section][0] if isinstance(s[section], list) else s.setdefault(section, {})
                t[key] = value
            return s
        return f

    return [("gate.threshold = 'high'", setter("gate", "threshold", "high"), True),
            ("gate.background_frames = '5'", setter("gate", "background_frames", "5"), True),
            ("runtime = 5", setter("top", "runtime", 5), True),
            ("sensor = [1, 2]", setter("top", "sensor", [1, 2]), True),
            ("sensor.fps = inf", setter("sensor", "fps", math.inf), True),
            ("sensor.fps = nan", setter("sensor", "fps", math.nan), True),
            ("output csv path is a directory", setter("output", "path", "/tmp"), False),
            ("base scene", lambda s: s, False)]


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
    """(argv, allowed exit codes, words the message must contain) of bad arguments: all exit 2."""
    afile = folder / "a_file.txt"
    afile.write_text("x")
    bundle = str(default_bundle_dir())
    return [
        (["synth", "--n", "0", "--out", str(folder / "s1")], {2}, ("--n",)),
        (["synth", "--out", str(afile), "--n", "5"], {2}, ("--out",)),
        (["synth", "--out", str(folder / "s2"), "--n", "2", "--edge-fraction", "2"], {2}, ("--edge-fraction",)),
        (["synth", "--out", str(folder / "s3"), "--n", "2", "--frames-per-grasp", "0"], {2}, ("--frames-per-grasp",)),
        (["quantize", bundle, "--out", str(folder / "q"), "--max-frames", "0"], {2}, ("--max-frames",)),
        (["quantize", bundle, "--out", str(folder / "q"), "--min-frames", "0"], {2}, ("--min-frames",)),
        (["quantize", bundle, "--out", str(folder / "q"), "--min-frames", "50", "--max-frames", "10"], {2},
         ("--min-frames",)),
        (["export", str(afile), "--out", str(folder / "e"), "--opset", "99"], {2}, ("--opset",)),
        (["export", str(afile), "--out", str(folder / "e"), "--opset", "12"], {2}, ("--opset",)),
        (["record"], {2}, ("--sensor",)),
        (["record", "--repair", str(folder / "nope")], {2}, ("nope",)),
        (["record", "--sensor", "0", "--out", str(folder / "r"), "--every", "0"], {2}, ("--every",)),
    ]


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


# =============================================================================== record faults
KILL_PHASES = ("image_tmp", "image_done", "meta_partial", "meta_done", "force_tmp", "force_done")
KILL_AFTER = 3  # complete samples before the kill


def probe_kill(folder: Path, phase: str) -> Verdict:
    """kill -9 of a recording at ``phase`` of sample KILL_AFTER; then resume: every complete
    sample must still read, the dataset must load, and recording must continue after it."""
    from tactile_force.edge.data.dataset import AuthorsDataset
    from tactile_force.firmware_bridge.recorder import RecordOptions, record

    out = folder / f"kill_{phase}"
    shutil.rmtree(out, ignore_errors=True)
    env = {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    proc = subprocess.run([sys.executable, str(KILL_WORKER), str(out), phase, str(KILL_AFTER)], env=env,
                          capture_output=True, text=True, timeout=120)
    if proc.returncode != -signal.SIGKILL:
        return Verdict(Outcome.TRACEBACK, f"{phase}: worker exit {proc.returncode}: {proc.stderr[-300:]}")
    complete = KILL_AFTER + (1 if phase == "force_done" else 0)
    res = record(NoiseFrames(seed=99), FixedScale(2.5), RecordOptions(out=out, max_samples=1, handle_signals=False))
    try:
        ds = AuthorsDataset(out)
        samples = list(ds)
    except BaseException as exc:  # noqa: BLE001
        return Verdict(Outcome.TRACEBACK, f"{phase}: unreadable after resume: {exc}")
    if len(samples) < complete + 1:
        return Verdict(Outcome.DATA_LOST, f"{phase}: {len(samples)} samples after resume, expected {complete + 1}")
    if len(samples) > complete + 1 or res.written != [complete]:
        return Verdict(Outcome.SILENT_WRONG, f"{phase}: {len(samples)} samples, resumed at {res.written}")
    if sorted(ds.meta) != [s.id for s in samples]:
        return Verdict(Outcome.SILENT_WRONG,
                       f"{phase}: meta ids {sorted(ds.meta)} vs samples {[s.id for s in samples]}")
    repairs = getattr(res, "repairs", None)
    changed = bool(repairs[0].changed) if repairs else bool(res.removed_unlabelled)
    return Verdict(Outcome.CLEAR if changed else Outcome.ACCEPTED,
                   f"{phase}: {complete} complete samples kept"
                   + (f"; repaired: {repairs[0].describe()}" if repairs else ""))


def probe_truncation(folder: Path, cut: int) -> Verdict:
    """A power cut truncates meta.jsonl ``cut`` bytes into its last line: the reader names the
    file and line until repaired; ``record --repair`` keeps every complete sample."""
    from tactile_force.edge.data.dataset import AuthorsDataset

    src = folder / "trunc_src"
    if not src.is_dir():
        make_dataset(src, n=4)
    out = folder / "trunc"
    shutil.rmtree(out, ignore_errors=True)
    shutil.copytree(src, out)
    meta = out / "meta.jsonl"
    data = meta.read_bytes()
    last = data.rstrip(b"\n").rfind(b"\n") + 1
    meta.write_bytes(data[:last + cut])
    verdicts = []
    partial = 0 < cut < len(data) - last - 1
    if partial:
        try:
            AuthorsDataset(out)
            verdicts.append(Verdict(Outcome.SILENT_WRONG, f"cut {cut}: a cut-short line read without complaint"))
        except BaseException as exc:  # noqa: BLE001
            verdicts.append(refusal(exc, True, names=("meta.jsonl", "line 4", "--repair")))
    verdicts.append(cli_verdict(["record", "--repair", str(out)], {0}, False))
    try:
        samples = list(AuthorsDataset(out))
    except BaseException as exc:  # noqa: BLE001
        return worst([*verdicts, Verdict(Outcome.DATA_LOST, f"cut {cut}: unreadable after repair: {exc}")])
    if len(samples) != 4:
        verdicts.append(Verdict(Outcome.DATA_LOST, f"cut {cut}: {len(samples)} of 4 samples after repair"))
    w = worst(verdicts)
    return Verdict(w.outcome, f"cut {cut}: {w.detail}")


class NoiseFrames:
    """A frame source of incompressible random frames (fills a disk fast), forever."""

    name = "noise"

    def __init__(self, seed: int = 0) -> None:
        from tactile_force.edge.frames import SourceStats

        self.rng = np.random.default_rng(seed)
        self.i = 0
        self.stats = SourceStats()

    def read(self):
        from tactile_force.edge.frames import TimedFrame

        self.i += 1
        return TimedFrame(self.rng.integers(0, 256, (320, 240, 3), dtype=np.uint8), self.i * 1000, self.i)


class FixedScale:
    """The newest reading of a HID POS scale, decoded from a real report by parse_scale_report."""

    def __init__(self, force_n: float) -> None:
        self.grams = int(round(force_n / 9.80665 * 1000))

    def read(self):
        from tactile_force.firmware_bridge.hid_scale import parse_scale_report

        g = self.grams
        return parse_scale_report([0x03, 0x04, 0x02, 0x00, g & 0xFF, (g >> 8) & 0xFF])


@contextlib.contextmanager
def small_filesystem(folder: Path, size_kib: int = 1536) -> Iterator[tuple[Path, str]]:
    """A small real filesystem (tmpfs, needs root) at ``folder``; else the same folder with every
    write past ``size_kib`` failing with ENOSPC (a patched AuthorsDatasetWriter). Yields (path, method)."""
    folder.mkdir(parents=True, exist_ok=True)
    mounted = False
    if hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("mount"):
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kib}k", "tmpfs", str(folder)],
                           capture_output=True, text=True)
        mounted = r.returncode == 0
    if mounted:
        try:
            yield folder, f"tmpfs of {size_kib} KiB (mount -t tmpfs)"
        finally:
            subprocess.run(["umount", str(folder)], capture_output=True)
        return
    import errno

    from tactile_force.edge.data import dataset as ds_mod

    budget = {"left": size_kib * 1024}
    orig_atomic = ds_mod.AuthorsDatasetWriter._atomic_write

    def atomic(path: Path, data: bytes) -> None:
        if len(data) > budget["left"]:
            tmp = path.with_name(f".{path.name}.tmp")
            tmp.write_bytes(data[:budget["left"]])
            budget["left"] = 0
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp))
        budget["left"] -= len(data)
        orig_atomic(path, data)

    ds_mod.AuthorsDatasetWriter._atomic_write = staticmethod(atomic)
    try:
        yield folder, f"simulated: writes past {size_kib} KiB raise ENOSPC (not root: no tmpfs)"
    finally:
        ds_mod.AuthorsDatasetWriter._atomic_write = staticmethod(orig_atomic)


def probe_disk_full(folder: Path) -> tuple[Verdict, str]:
    """Record onto a small filesystem until it is full, through the CLI (DIGIT and HID scale
    faked at the hardware boundary): exit 1, summary printed, every sample written readable."""
    from tactile_force.edge.data.dataset import AuthorsDataset

    with small_filesystem(folder / "small_fs") as (fs, method):
        out = fs / "ds"
        rc, stdout, stderr = _record_cli_with_fakes(["record", "--sensor", "0", "--out", str(out)])
        verdicts = []
        m = re.search(r"wrote (\d+) sample", stdout)
        if "Traceback" in stdout + stderr:
            verdicts.append(Verdict(Outcome.TRACEBACK, stderr[-300:]))
        elif rc == 0 or "disk full" not in stderr or not m:
            verdicts.append(Verdict(Outcome.SILENT_WRONG,
                                    f"exit {rc}; stdout {stdout[-200:]!r}; stderr {stderr[-200:]!r}"))
        written = int(m.group(1)) if m else None  # no summary: judged above, not as data lost
        try:
            n = len(list(AuthorsDataset(out)))
            leftovers = [p.name for p in out.rglob(".*.tmp")]
            if n < 1 or (written is not None and n != written):
                verdicts.append(Verdict(Outcome.DATA_LOST, f"{n} samples read back, summary says {written}"))
            elif leftovers:
                verdicts.append(Verdict(Outcome.SILENT_WRONG, f"temp files left: {leftovers}"))
        except BaseException as exc:  # noqa: BLE001
            verdicts.append(Verdict(Outcome.DATA_LOST, f"unreadable after disk full: {exc}"))
        if not verdicts:
            verdicts.append(Verdict(Outcome.CLEAR, f"exit {rc}, {written} samples kept: {stderr.strip()[:160]}"))
        return worst(verdicts), method


def _record_cli_with_fakes(argv: list[str]) -> tuple[int, str, str]:
    """``tactile-force record`` with DigitSource and HidScale replaced by fakes (hardware boundary)."""
    from tactile_force.firmware_bridge import digit, hid_scale

    class FakeDigit(NoiseFrames):
        def __init__(self, options) -> None:
            super().__init__(seed=1)
            self.node = "/dev/video-fake"

        def __enter__(self):
            return self

        def __exit__(self, *exc) -> None:
            pass

    class FakeScaleHandle(FixedScale):
        name = "fake HID scale"

        def close(self) -> None:
            pass

    old_src, old_open = digit.DigitSource, hid_scale.HidScale.open
    digit.DigitSource = FakeDigit
    hid_scale.HidScale.open = classmethod(lambda cls, options=None: FakeScaleHandle(3.0))
    try:
        return run_cli(argv)
    finally:
        digit.DigitSource = old_src
        hid_scale.HidScale.open = old_open


def probe_replay_vanish(folder: Path, paced: bool) -> Verdict:
    """A replay folder deleted mid-run: the next read raises SourceError (never idles)."""
    from tactile_force.edge.sources import ReplayFolderSource

    root = folder / f"vanish_{paced}"
    shutil.rmtree(root, ignore_errors=True)
    make_dataset(root, n=10)

    def run() -> Verdict:
        src = ReplayFolderSource(root, fps=200.0 if paced else None)
        for _ in range(3):
            if src.read() is None:
                return Verdict(Outcome.SILENT_WRONG, "ended early")
        shutil.rmtree(root)
        try:
            got = src.read()
        except BaseException as exc:  # noqa: BLE001
            return refusal(exc, True, names=("disappeared",))
        return Verdict(Outcome.SILENT_WRONG, f"read after deletion returned {type(got).__name__}, "
                                             f"{src.stats.corrupt} counted corrupt")

    return with_timeout(run, 20.0)


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
        if i19.mcap_available():
            replay = i19.mcap_replay(base)
            for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGKILL):
                t.add(i19.probe_mcap_signal(base, replay, sig))
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
                    "category is judged by are below the table."),
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
