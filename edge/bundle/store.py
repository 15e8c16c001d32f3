"""Model bundles on disk: an ONNX file plus its manifest, the only thing edge/ needs.

A bundle is a folder ``NAME/`` holding ``model.onnx`` and ``model.json``, or a loose
``NAME.onnx`` with a sibling ``NAME.json``. :func:`load_bundle` makes every check
``tactile-force bundle verify`` makes from the files (one check, :func:`check_bundle_files`,
for every loader): no file of the bundle resolves outside it (symbolic links), the manifest
validates with its records (:mod:`.manifest`), the ONNX file's sha256 matches, and every
claim the graph can contradict agrees with it (:func:`.graph_facts.manifest_problems`: the
precision, the network input size, the inputs against the variant; the graph's facts are
read once per sha256). :func:`write_bundle` refuses to write a bundle that would fail them.

Writing is crash-safe in every window. :func:`write_bundle` writes every file into a
hidden sibling ``.NAME.XXXX.partial`` (fsync'd, with the writer's pid), then:

- a new ``NAME`` appears by one ``rename``;
- an existing ``NAME`` is swapped with the new folder by one ``renameat2(RENAME_EXCHANGE)``
  (Linux), so ``NAME`` is at every instant either the old complete bundle or the new one.
  Where the exchange is unavailable, the old folder is first renamed to ``.NAME.old``; a
  crash between the two renames is repaired by the next :func:`load_bundle` or
  :func:`write_bundle` (``.NAME.old`` moves back).

Partials left by a killed writer (its pid no longer alive) are removed by the next write
to the same place, or listed by :func:`stale_partials`.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from ..errors import BundleError
from ..files.atomic import _named, rename_noreplace
from ..files.atomic import exchange as _exchange
from ..files.atomic import fsync_dir as _fsync_dir
from .manifest import Manifest, manifest_from_json

_PID_FILE = ".writer-pid"


@dataclass
class Bundle:
    """A verified bundle on disk."""

    path: Path
    onnx_path: Path
    manifest: Manifest

    @property
    def variant(self) -> str:
        """The variant's name, e.g. ``'rgbmod'``."""
        return self.manifest.variant.value

    @property
    def name(self) -> str:
        return self.manifest.name or self.path.stem


def sha256_file(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex sha256 of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def _locate(path: Path) -> tuple[Path, Path]:
    """(onnx_path, manifest_path) for a bundle folder or a loose .onnx/.json pair."""
    if path.is_dir():
        return path / "model.onnx", path / "model.json"
    if path.suffix == ".onnx":
        return path, path.with_suffix(".json")
    if path.suffix == ".json":
        return path.with_suffix(".onnx"), path
    raise BundleError(f"{path}: not a bundle (expected a folder with model.onnx + model.json, "
                      "or NAME.onnx with NAME.json)")


def read_manifest(path: str | os.PathLike) -> Manifest:
    """Read and validate a ``model.json`` file (format 1 is migrated)."""
    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8")
        raw = json.loads(text)
    except UnicodeDecodeError:
        raise BundleError(f"{p}: manifest is not UTF-8 text; the file is damaged or not a manifest") from None
    except json.JSONDecodeError as exc:
        raise BundleError(f"{p}: manifest is not valid JSON ({exc.msg} at line {exc.lineno}); "
                          "the file may be truncated") from None
    except OSError as exc:
        raise BundleError(f"{p}: cannot read the manifest ({exc.strerror})") from None
    return manifest_from_json(raw, source=str(p))


def files_outside(path: str | os.PathLike) -> str:
    """Which of a bundle's files (the folder's entries, or a loose NAME.onnx / NAME.json pair)
    resolve outside it through a symbolic link, as one line, or ""."""
    p = Path(path)
    if p.is_dir():
        root, files = p.resolve(), sorted(p.iterdir())
    else:
        root = p.parent.resolve()
        files = [f for f in (p.with_suffix(".onnx"), p.with_suffix(".json")) if f.exists() or f.is_symlink()]
    bad = []
    for f in files:
        if not f.is_symlink():
            continue
        target = f.resolve()
        if target != root and root not in target.parents:
            bad.append(f"{f.name} -> {target}")
    return f"file(s) resolve outside the bundle: {', '.join(bad)}" if bad else ""


def check_bundle_files(path: Path, onnx_path: Path, manifest: Manifest, data: bytes) -> None:
    """The one check every loader and ``bundle verify`` make of a bundle's files: the sha256
    of ``data`` (the ONNX file's bytes) against the manifest, then every manifest claim the
    graph can contradict (:func:`.graph_facts.manifest_problems`; the graph's facts are read
    once per sha256). Raises :class:`BundleError` naming the bundle and the failing field."""
    from .graph_facts import facts_by_sha256, manifest_problems

    digest = hashlib.sha256(data).hexdigest()
    if digest != manifest.sha256:
        raise BundleError(
            f"{onnx_path}: sha256 {digest[:12]}... does not match the manifest's {manifest.sha256[:12]}...; "
            "the model file is corrupted, truncated or belongs to another bundle. Re-export it."
        )
    problems = manifest_problems(manifest, facts_by_sha256(digest, data, onnx_path))
    if problems:
        raise BundleError(f"{path}: the manifest contradicts its graph {onnx_path.name}: {'; '.join(problems)}; "
                          "expected a manifest that says what the graph holds (bundle verify refuses this bundle)")


def load_bundle(path: str | os.PathLike, verify: bool = True) -> Bundle:
    """Read and verify a bundle: every check ``tactile-force bundle verify`` makes from the files.

    Parameters
    ----------
    path
        A bundle folder, or a loose ``NAME.onnx`` / ``NAME.json``.
    verify
        Check the ONNX file's sha256 and the manifest's claims against the graph
        (:func:`check_bundle_files`; default). The files' places and the manifest's own
        consistency are checked either way.

    Returns
    -------
    Bundle

    Raises
    ------
    BundleError
        With the reason: missing files, a file linked from outside the bundle, a manifest
        that does not validate, a hash mismatch, a manifest claim the graph contradicts.
    """
    p = Path(path)
    if not p.exists():
        _recover(p)
    if not p.exists():
        raise BundleError(f"{p}: bundle not found")
    onnx_path, man_path = _locate(p)
    outside = files_outside(p)
    if outside:
        raise BundleError(f"{p}: {outside}; a bundle's files must lie in its folder (copy the file in, or write the "
                          "bundle again)")
    if not man_path.is_file():
        raise BundleError(f"{man_path}: manifest missing; a bundle needs its JSON manifest next to the ONNX file")
    manifest = read_manifest(man_path)
    if p.is_dir():
        onnx_path = p / manifest.onnx_file  # a plain file name: the manifest check refuses paths
    if not onnx_path.is_file():
        raise BundleError(f"{onnx_path}: ONNX file missing")
    if onnx_path.stat().st_size == 0:
        raise BundleError(f"{onnx_path}: ONNX file is empty")
    if verify:
        try:
            data = onnx_path.read_bytes()
        except OSError as exc:
            raise BundleError(f"{onnx_path}: cannot read the ONNX file ({exc.strerror})") from None
        check_bundle_files(p, onnx_path, manifest, data)
    return Bundle(path=p, onnx_path=onnx_path, manifest=manifest)


def _phase(name: str) -> None:
    """A named point in :func:`write_bundle` (crash tests replace it to kill the writer there)."""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def stale_partials(dest: str | os.PathLike) -> list[Path]:
    """Partial folders of ``dest`` whose writer is gone (killed mid-write)."""
    dest = Path(dest)
    out = []
    for cand in dest.parent.glob(f".{dest.name}.*.partial"):
        pid_file = cand / _PID_FILE
        if cand.is_symlink() or not (pid_file.is_file() or (cand / "model.json").is_file()):
            continue  # neither a bundle writer's partial nor a swapped-out bundle: never removed
        try:
            pid = int(pid_file.read_text().strip())
        except (OSError, ValueError):
            pid = -1
        if pid <= 0 or not _pid_alive(pid):
            out.append(cand)
    return out


def _recover(dest: Path) -> None:
    """Repair an interrupted two-rename swap: ``.NAME.old`` is the last complete bundle."""
    old = dest.with_name(f".{dest.name}.old")
    if old.is_dir():
        if dest.exists():
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(old, dest)
            _fsync_dir(dest.parent)


def write_bundle(dest: str | os.PathLike, onnx_bytes: bytes, manifest: Manifest,
                 extra_files: dict[str, bytes] | None = None, overwrite: bool = False,
                 inputs: Iterable[tuple[str, str | os.PathLike | None]] = ()) -> Bundle:
    """Write a bundle folder crash-safely and return it verified.

    Parameters
    ----------
    dest
        The bundle folder to create (or replace, with ``overwrite``).
    onnx_bytes
        The serialized ONNX model.
    manifest
        Its manifest; ``sha256`` and ``onnx_file`` are filled in here.
    extra_files
        More files to put in the folder (name -> bytes).
    overwrite
        Replace an existing ``dest`` (atomically); only a bundle folder or an empty folder.
    inputs
        (name, path) of everything the bundle was made from: ``dest`` must not be, hold or lie
        inside any of them (:func:`~tactile_force.edge.files.guard.check_output`), overwrite or not.

    Returns
    -------
    Bundle
        The written bundle, read back and verified.
    """
    dest = Path(dest)
    if dest.is_symlink():  # the link itself would be swapped out (and left hidden): never replaced
        raise BundleError(f"{dest}: is a symbolic link (to {os.readlink(dest)}); a bundle is never written through "
                          f"a link nor replaces one: give the folder itself ({os.path.realpath(dest)}) or a new path")
    if inputs:
        from ..files.guard import OutputKind, check_output

        check_output(dest, inputs, force=True, kind=OutputKind.BUNDLE, flag="bundle destination")
    from ..files.claim import OutputClaim

    with OutputClaim(dest, "bundle", flag="bundle destination"):  # one writer at a time, judged first
        return _write_claimed(dest, onnx_bytes, manifest, extra_files, overwrite)


def _write_claimed(dest: Path, onnx_bytes: bytes, manifest: Manifest, extra_files: dict[str, bytes] | None,
                   overwrite: bool) -> Bundle:
    """:func:`write_bundle` once ``dest`` is claimed."""
    _recover(dest)
    for stale in stale_partials(dest):
        shutil.rmtree(stale, ignore_errors=True)
    if dest.exists() and not overwrite:
        raise BundleError(f"{dest}: already exists (pass overwrite=True / --force to replace it)")
    if dest.exists() and not dest.is_dir():
        raise BundleError(f"{dest}: exists and is not a bundle folder; refusing to replace it")
    if dest.is_dir() and any(dest.iterdir()) and not (dest / "model.json").is_file():
        raise BundleError(f"{dest}: is a folder of other files (no model.json), not a bundle; overwrite replaces "
                          "only a bundle folder: expected a new folder")
    if not onnx_bytes:
        raise BundleError(f"{dest}: refusing to write an empty ONNX model")
    manifest.sha256 = hashlib.sha256(onnx_bytes).hexdigest()
    manifest.onnx_file = "model.onnx"
    try:
        manifest.check()
    except ValueError as exc:
        raise BundleError(f"{dest}: refusing to write an inconsistent manifest ({exc})") from None
    manifest_text = manifest.to_json()
    try:  # every record as load_bundle will read it back (ordered ranges, a plain name, ...)
        manifest_from_json(json.loads(manifest_text), source=f"{dest}/model.json")
    except BundleError as exc:
        raise BundleError(f"refusing to write an inconsistent manifest: {exc}") from None
    check_bundle_files(dest, dest / "model.onnx", manifest, onnx_bytes)  # what load_bundle will check
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", suffix=".partial", dir=dest.parent))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it 0700; a bundle is readable like any folder
    try:
        (tmp / _PID_FILE).write_text(str(os.getpid()))
        files = {"model.onnx": onnx_bytes, "model.json": manifest_text.encode()}
        files.update(extra_files or {})
        for name, data in files.items():
            with open(tmp / name, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        _phase("files-written")
        (tmp / _PID_FILE).unlink()
        _fsync_dir(tmp)
        if not os.path.lexists(dest):
            if not rename_noreplace(tmp, dest):  # appeared meanwhile (not through this package: it is claimed)
                raise BundleError(f"{dest}: appeared while the bundle was written; nothing was replaced")
        elif _exchange(tmp, dest):
            _phase("exchanged")
            shutil.rmtree(tmp, ignore_errors=True)  # tmp now holds the old bundle
        else:
            old = dest.with_name(f".{dest.name}.old")
            os.replace(dest, old)
            _phase("old-moved")
            os.replace(tmp, dest)
            shutil.rmtree(old, ignore_errors=True)
        _fsync_dir(dest.parent)
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        _recover(dest)
        if isinstance(exc, OSError) and (named := _named(exc, tmp, dest)) is not exc:
            raise named from exc  # a full disk names the bundle, not its hidden staging folder
        raise
    return load_bundle(dest)
