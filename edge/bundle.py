"""Model bundles: an ONNX file plus a JSON manifest, the only thing edge/ needs.

A bundle is a folder ``NAME/`` holding ``model.onnx`` and ``model.json``, or a loose
``NAME.onnx`` with a sibling ``NAME.json``. The manifest records what the graph expects
and how it was made; :func:`load_bundle` refuses a bundle whose ONNX file does not match
the manifest's sha256. :func:`write_bundle` writes a folder atomically: everything goes to
a temporary sibling folder that is renamed into place only when complete.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from .errors import BundleError

FORMAT_VERSION = 1
VARIANTS = ("rgbmod", "d", "dmod", "rgbmod+d")
#: Variants whose graph takes a depth image and so need the depth stage at run time.
DEPTH_VARIANTS = ("d", "dmod", "rgbmod+d")
PRECISIONS = ("fp32", "fp16", "int8-static", "int8-dynamic")


@dataclass
class TensorSpec:
    """One graph input or output.

    shape uses -1 for the dynamic batch; for inputs: dtype 'uint8', layout 'NHWC',
    colour_order 'BGR' (rgb input) or 'GRAY' (depth input), and what the graph does to it.
    """

    name: str
    shape: list[int]
    dtype: str
    kind: str = "rgb"  # 'rgb' | 'depth' | 'force'
    layout: str = "NHWC"
    colour_order: str = "BGR"
    scaling: str = "x / 255 inside the graph"
    unit: str = ""


@dataclass
class Manifest:
    """The JSON manifest of a bundle (see design.md)."""

    variant: str
    precision: str
    inputs: list[TensorSpec]
    output: TensorSpec
    sha256: str = ""
    onnx_file: str = "model.onnx"
    format_version: int = FORMAT_VERSION
    name: str = ""
    preprocessing_in_graph: list[str] = field(default_factory=list)
    architecture: dict[str, Any] = field(default_factory=dict)  # input_scale, width, head_folded, gmacs
    quantization: dict[str, Any] | None = None  # method, calibration data, per_channel, nodes kept float
    parity: dict[str, Any] = field(default_factory=dict)  # max_abs_diff_n vs torch, frames
    error: dict[str, Any] = field(default_factory=dict)  # RE/MAE vs ground truth and vs fp32
    provenance: dict[str, Any] = field(default_factory=dict)  # checkpoint, sha256, trained_on, note
    created_by: str = "tactile-force"

    @property
    def needs_depth(self) -> bool:
        return self.variant in DEPTH_VARIANTS

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2, sort_keys=False) + "\n"

    @classmethod
    def from_dict(cls, d: dict, source: str = "manifest") -> "Manifest":
        try:
            d = dict(d)
            d["inputs"] = [TensorSpec(**s) for s in d["inputs"]]
            d["output"] = TensorSpec(**d["output"])
            m = cls(**d)
        except (KeyError, TypeError) as exc:
            raise BundleError(f"{source}: not a tactile-force manifest ({exc})") from None
        if m.format_version != FORMAT_VERSION:
            raise BundleError(f"{source}: manifest format_version {m.format_version}, this package reads {FORMAT_VERSION}")
        if m.variant not in VARIANTS:
            raise BundleError(f"{source}: unknown variant {m.variant!r}; expected one of {VARIANTS}")
        return m


@dataclass
class Bundle:
    """A verified bundle on disk."""

    path: Path
    onnx_path: Path
    manifest: Manifest

    @property
    def variant(self) -> str:
        return self.manifest.variant

    @property
    def name(self) -> str:
        return self.manifest.name or self.path.stem


def sha256_file(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def _locate(path: Path) -> tuple[Path, Path]:
    """(onnx_path, manifest_path) for a bundle folder or a loose .onnx/.json pair."""
    if path.is_dir():
        man = path / "model.json"
        if not man.is_file():
            jsons = sorted(path.glob("*.json"))
            if len(jsons) != 1:
                raise BundleError(f"{path}: bundle folder has no model.json manifest")
            man = jsons[0]
        return path / "model.onnx", man
    if path.suffix == ".onnx":
        return path, path.with_suffix(".json")
    if path.suffix == ".json":
        return path.with_suffix(".onnx"), path
    raise BundleError(f"{path}: not a bundle (expected a folder with model.onnx + model.json, or NAME.onnx with NAME.json)")


def load_bundle(path: str | os.PathLike, verify: bool = True) -> Bundle:
    """Read and verify a bundle; BundleError with the reason if anything is off."""
    p = Path(path)
    if not p.exists():
        raise BundleError(f"{p}: bundle not found")
    onnx_path, man_path = _locate(p)
    if not man_path.is_file():
        raise BundleError(f"{man_path}: manifest missing; a bundle needs its JSON manifest next to the ONNX file")
    try:
        raw = json.loads(man_path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise BundleError(f"{man_path}: manifest is not valid JSON ({exc}); the file may be truncated") from None
    manifest = Manifest.from_dict(raw, source=str(man_path))
    if manifest.onnx_file and p.is_dir():
        onnx_path = p / manifest.onnx_file
    if not onnx_path.is_file():
        raise BundleError(f"{onnx_path}: ONNX file missing")
    if onnx_path.stat().st_size == 0:
        raise BundleError(f"{onnx_path}: ONNX file is empty")
    if verify:
        digest = sha256_file(onnx_path)
        if digest != manifest.sha256:
            raise BundleError(
                f"{onnx_path}: sha256 {digest[:12]}... does not match the manifest's {manifest.sha256[:12]}...; "
                "the model file is corrupted, truncated or belongs to another bundle. Re-export it."
            )
    return Bundle(path=p, onnx_path=onnx_path, manifest=manifest)


def write_bundle(dest: str | os.PathLike, onnx_bytes: bytes, manifest: Manifest,
                 extra_files: dict[str, bytes] | None = None, overwrite: bool = False) -> Bundle:
    """Write a bundle folder atomically and return it verified.

    The sha256 field of ``manifest`` is filled in here. Nothing appears at ``dest``
    unless every file was written; an existing ``dest`` is replaced only with
    ``overwrite=True``.
    """
    dest = Path(dest)
    if dest.exists() and not overwrite:
        raise BundleError(f"{dest}: already exists (pass overwrite=True / --force to replace it)")
    if not onnx_bytes:
        raise BundleError(f"{dest}: refusing to write an empty ONNX model")
    dest.parent.mkdir(parents=True, exist_ok=True)
    manifest.sha256 = hashlib.sha256(onnx_bytes).hexdigest()
    manifest.onnx_file = "model.onnx"
    tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", suffix=".partial", dir=dest.parent))
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it 0700; a bundle is readable like any folder
    try:
        files = {"model.onnx": onnx_bytes, "model.json": manifest.to_json().encode()}
        files.update(extra_files or {})
        for name, data in files.items():
            with open(tmp / name, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        if dest.exists():
            old = dest.with_name(f".{dest.name}.old")
            shutil.rmtree(old, ignore_errors=True)
            os.replace(dest, old)
            os.replace(tmp, dest)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, dest)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return load_bundle(dest)
