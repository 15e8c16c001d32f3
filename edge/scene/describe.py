"""Writing a scene back to TOML (``run --save-scene``) and describing it (``scene show``)."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path
from typing import Any

from ..errors import BundleError, SceneError
from ..gate.options import GateOptions
from .kinds import kind_of
from .model import OutputSpec, Scene, default_bundle_path
from .read import _out_path, output_problem


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, (str, Path)):
        return json.dumps(str(v))
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {v!r} to TOML")


def scene_to_toml(scene: Scene) -> str:
    """The scene as a TOML file that :func:`load_scene` reads back to an equal Scene
    (absolute paths; gate keys only where they differ from the source kind's preset)."""
    lines = ["# written by tactile-force run --save-scene", "", "[runtime]"]
    bundles = ["default" if b == default_bundle_path() else str(b) for b in scene.bundles]
    rt: dict[str, Any] = {"bundle": bundles[0] if len(bundles) == 1 else bundles, "backend": scene.backend,
                          "deadline_ms": scene.deadline_ms, "threads": scene.threads,
                          "max_frames": scene.max_frames, "report_stale": scene.report_stale}
    for k, v in (("fallback", scene.fallback), ("oak_archive", scene.oak_archive), ("oak_device", scene.oak_device)):
        if v is not None:
            rt[k] = v
    lines += [f"{k} = {_toml_value(v)}" for k, v in rt.items()]
    if depth := scene.depth.given():
        lines += ["", "[depth]"] + [f"{k} = {_toml_value(v)}" for k, v in depth.items()]
    for s in scene.sensors:
        kind = kind_of(s)
        lines += ["", "[[sensor]]", f"name = {_toml_value(s.name)}", f"source = {_toml_value(s.source)}"]
        for k in kind.key_names:
            v = getattr(s, k)
            if v is not None:
                lines.append(f"{k} = {_toml_value(int(v) if k == 'fps' and s.source == 'digit' else v)}")
        if s.background is not None:
            lines.append(f"background = {_toml_value(s.background)}")
        preset = kind.gate_preset()
        diff = {f.name: getattr(s.gate, f.name) for f in dataclasses.fields(GateOptions)
                if getattr(s.gate, f.name) != getattr(preset, f.name)}
        if diff:
            lines.append(f"gate = {_toml_value(diff)}")
    for o in scene.outputs:
        lines += ["", "[[output]]", f"kind = {_toml_value(o.kind)}"]
        for k in ("path", "topic"):
            if getattr(o, k) is not None:
                lines.append(f"{k} = {_toml_value(getattr(o, k))}")
        if o.kind == "zenoh":
            lines += [f"{k} = {_toml_value(getattr(o, k))}" for k in ("endpoint", "mode", "namespace", "node")
                      if getattr(o, k) is not None]
        for k in ("live", "fsync", "frames", "mask", "retry"):
            if getattr(o, k):
                lines.append(f"{k} = true")
    return "\n".join(lines) + "\n"


def save_scene(scene: Scene, path: str | os.PathLike) -> Path:
    """Write :func:`scene_to_toml` to ``path`` (relative to the working directory), in one step
    (a reader never sees half a file; an interrupted write leaves ``path`` as it was)."""
    p = _out_path(str(path), "--save-scene")
    if problem := output_problem(p):
        raise SceneError(f"--save-scene: {problem}")
    from ..files.atomic import staged_file

    with staged_file(p) as tmp:
        tmp.write_text(scene_to_toml(scene))
    return p


# -- planning ---------------------------------------------------------------------------
def _bundle_summary(path: Path) -> tuple[bool | None, str]:
    """(needs_depth or None if unreadable, one-line description)."""
    from ..bundle.store import load_bundle

    try:
        b = load_bundle(path)
    except BundleError as exc:
        return None, f"{path}: NOT USABLE ({exc})"
    m = b.manifest
    return m.needs_depth, f"{b.name}: variant {m.variant}, {m.precision}, sha256 ok ({path})"


def bundle_problems(scene: Scene) -> list[str]:
    """Bundles that cannot be loaded (hash, manifest), one message each. Reads the bundles."""
    out = []
    for b in scene.bundles:
        nd, text = _bundle_summary(b)
        if nd is None:
            out.append(f"{scene.origin} [runtime] bundle: {text}")
    return out


def _output_line(o: OutputSpec) -> str:
    target = f" {o.path}" if o.path else (f" topic {o.topic}" if o.topic else "")
    if o.kind == "zenoh":
        from ..outputs.zenoh_topic import DEFAULT_ENDPOINT

        target += (f" node {o.namespace.rstrip('/')}/{o.node} ({o.mode} to {o.endpoint or DEFAULT_ENDPOINT}"
                   + (", retried" if o.retry else "") + ")")
    images = " + ".join(w for w, on in (("frames", o.frames), ("contact masks", o.mask)) if on)
    return (f"  output       {o.kind}{target}{' (live status line)' if o.live else ''}"
            + (f" (with {images})" if images else ""))


def describe_scene(scene: Scene) -> list[str]:
    """Human lines: the stages that will run, in order. Loads no model, opens no device."""
    lines = [f"scene {scene.origin}"]
    needs = []
    for b in scene.bundles:
        nd, text = _bundle_summary(b)
        needs.append(nd)
        lines.append(f"  bundle       {text}")
    needs_depth = any(n for n in needs if n is not None)
    if len(scene.bundles) > 1:
        lines.append(f"  ladder       measure p99 of {len(scene.bundles)} bundles at start; keep the most accurate "
                     f"within {scene.deadline_ms:g} ms")
    for s in scene.sensors:
        missing = "  [MISSING]" if s.path is not None and not s.path.exists() else ""
        lines.append(f"  source:{s.name:<6} {kind_of(s).describe(s)}{missing}")
        bg = (f"background from {s.background}" if s.background
              else f"background = mean of first {s.gate.background_frames} frames (learnt: keep the sensor untouched)")
        lines.append(f"  gate:{s.name:<8} threshold {s.gate.threshold:g}, on/off area {s.gate.on_area_frac:g}/"
                     f"{s.gate.off_area_frac:g}, downscale x{s.gate.downscale}, {bg}")
        if needs_depth:
            mapping = scene.depth.mapping or "from the bundle manifest, else MISSING: set [depth] mapping"
            mode = scene.depth.mode or "exact"
            ref = ", zero-depth reference = the gate's background" if mode == "paper" else ""
            lines.append(f"  depth:{s.name:<7} DepthStage {mode} (RGB -> normals -> gradients -> Poisson -> masked "
                         f"depth; mapping {mapping}{ref})")
    be = scene.backend + (f" {scene.oak_archive}" if scene.backend == "oak" else "")
    be += f" (fallback {scene.fallback})" if scene.fallback else ""
    lines.append(f"  inference    {be}, {scene.threads} thread(s), batch {len(scene.sensors)} when all in contact, "
                 f"deadline {scene.deadline_ms:g} ms")
    if not needs_depth:
        lines.append("  (no depth stage: RGB-only bundle)")
    lines += [_output_line(o) for o in scene.outputs or [OutputSpec("stdout")]]
    return lines
