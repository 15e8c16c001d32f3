"""Robustness cases of bundles every loader must refuse as ``bundle verify`` does, and of scene
paths that are not what they should be (the suite's categories "bundles verify refuses" and
"scene paths"; run by :func:`benchmarks.robustness.run_catalogue`).

- a manifest whose claims the graph contradicts (precision, input scale), a ``model.onnx`` or
  ``model.json`` linked from outside the bundle, a manifest whose records contradict
  themselves (``data_stats`` colour ranges swapped, a name with a path separator or a
  newline, a depth record on an RGBmod bundle): ``load_bundle``, ``run`` and ``bundle verify``
  each refuse it, naming the bundle and the field (accepted by any of them: SILENT_WRONG);
- a scene file that is a folder, a FIFO or a dangling link, and the shipped replay scene
  with its ``$TACTILE_FORCE_SHARED_DATA`` unset or empty: ``run --scene`` exits 2 saying what
  the path is, or naming the variable.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from .harness.cases import Outcome, Verdict, accepted, cli_verdict, default_bundle_dir, refusal, worst
from .robustness_table import rows, set_at

Case = tuple[str, Callable[[], Verdict]]


def _edited(dest: Path, edit: Callable[[dict], None], src: Path | None = None) -> Path:
    shutil.copytree(src or default_bundle_dir(), dest)
    raw = json.loads((dest / "model.json").read_text())
    edit(raw)
    (dest / "model.json").write_text(json.dumps(raw, indent=2))
    return dest


def _linked(dest: Path, name: str) -> Path:
    shutil.copytree(default_bundle_dir(), dest)
    outside = dest.parent / f"{dest.name}-outside-{name}"
    shutil.move(dest / name, outside)
    os.symlink(outside, dest / name)
    return dest


def _maker(row: dict[str, Any]) -> Callable[[Path], Path]:
    """How one ``[[bundle_lie]]`` row's bundle is made under a folder, from a copy of the shipped
    bundle its ``bundle`` names (default: the default): model.json keys set (a dotted key reaches
    into a record), two keys of a record swapped, or a file linked from outside."""
    if "link" in row:
        return lambda d: _linked(d, row["link"])

    def edit(m: dict) -> None:
        for dotted, value in row.get("set", {}).items():
            set_at(m, dotted.split("."), value)
        if "swap" in row:
            record, a, b = row["swap"]
            m[record][a], m[record][b] = m[record][b], m[record][a]
    src = default_bundle_dir().parent / row["bundle"] if "bundle" in row else None
    return lambda d: _edited(d, edit, src)


#: (what, how the bundle is made under a folder, the words a refusal must hold): the rows of
#: robustness_cases.toml ``[[bundle_lie]]``
BUNDLES: list[tuple[str, Callable[[Path], Path], tuple[str, ...]]] = [
    (row["what"], _maker(row), tuple(row["names"])) for row in rows("bundle_lie")]


def _probe_bundle(path: Path, names: tuple[str, ...]) -> Verdict:
    from tactile_force.edge import load_bundle

    try:
        load_bundle(path)
        loaded = accepted(True, "load_bundle accepted it")
    except BaseException as exc:  # noqa: BLE001 - classified
        loaded = refusal(exc, True, names=(str(path), *names))
    verdicts = [loaded,
                cli_verdict(["bundle", "verify", str(path)], {1}, True, (str(path), *names)),
                cli_verdict(["run", "--source", "virtual", "--bundle", str(path), "--max-frames", "2"], {2}, True,
                            (str(path), *names))]
    return worst(verdicts)


def bundle_cases(folder: Path) -> list[Case]:
    """One case per bundle of :data:`BUNDLES`, made under ``folder``."""
    out: list[Case] = []
    for i, (what, make, names) in enumerate(BUNDLES):
        def probe(i: int = i, make: Callable[[Path], Path] = make, names: tuple[str, ...] = names) -> Verdict:
            return _probe_bundle(make(folder / f"b{i}"), names)
        out.append((what, probe))
    return out


@contextlib.contextmanager
def _env(name: str, value: str | None) -> Iterator[None]:
    old = os.environ.get(name)
    if value is None:
        os.environ.pop(name, None)
    else:
        os.environ[name] = value
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = old


def scene_path_cases(folder: Path) -> list[Case]:
    """A scene file that is a folder, a FIFO, a dangling link; the shipped replay scene with
    its data variable unset or empty."""
    folder.mkdir(parents=True, exist_ok=True)
    as_folder, fifo, dangling = folder / "folder.toml", folder / "fifo.toml", folder / "dangling.toml"
    as_folder.mkdir(exist_ok=True)
    if not fifo.exists():
        os.mkfifo(fifo)
    if not dangling.is_symlink():
        os.symlink(folder / "gone.toml", dangling)
    out: list[Case] = [
        (f"--scene {p.name} ({what})",
         lambda p=p, what=what: cli_verdict(["run", "--scene", str(p)], {2}, True, (str(p), what, "regular TOML file")))
        for p, what in ((as_folder, "is a folder"), (fifo, "is a FIFO"), (dangling, "symbolic link to a missing"))]
    from tactile_force.edge.scene import PACKAGE_DIR

    scene = PACKAGE_DIR / "scenes" / "replay_rgbmod.toml"
    for value, state in ((None, "is not set"), ("", "is empty")):
        def probe(value: str | None = value, state: str = state) -> Verdict:
            with _env("TACTILE_FORCE_SHARED_DATA", value):
                return cli_verdict(["run", "--scene", str(scene)], {2}, True,
                                   (f"$TACTILE_FORCE_SHARED_DATA {state}",))
        out.append((f"shipped replay scene, TACTILE_FORCE_SHARED_DATA {state}", probe))
    return out


__all__ = ["BUNDLES", "Outcome", "bundle_cases", "scene_path_cases"]
