"""The manifest's format version and the checks of the names it holds (the bundle's ``name``,
its ``onnx_file``); edge/bundle/manifest.py re-exports them."""

from __future__ import annotations

from pathlib import PurePosixPath, PureWindowsPath

FORMAT_VERSION = 3


#: The longest bundle ``name`` (characters): a name is shown on every line that names the bundle.
MAX_NAME_CHARS = 128


def check_bundle_name(name: str) -> None:
    """Raise ValueError unless ``name`` is a plain name ("" or at most :data:`MAX_NAME_CHARS`
    characters, no path separator, no control character or newline, not ``.`` / ``..``): it
    is printed in every reading's log line and used as a folder name by the tools."""
    if not name:
        return
    bad = next((c for c in name if ord(c) < 32 or ord(c) == 127 or c in "/\\"), None)
    if bad is not None or name in (".", "..") or len(name) > MAX_NAME_CHARS or name.strip() != name:
        why = (f"holds {bad!r}" if bad is not None else f"is {len(name)} characters" if len(name) > MAX_NAME_CHARS
               else "is not a plain name")
        raise ValueError(f"name {name[:60]!r}{'...' if len(name) > 60 else ''} {why}; expected a plain name (no path "
                         f"separator, control character or newline, no leading or trailing space, at most "
                         f"{MAX_NAME_CHARS} characters)")


def check_onnx_file_name(name: str) -> None:
    """Raise ValueError unless ``name`` is a plain file name inside the bundle folder."""
    if (not name or name in (".", "..") or PurePosixPath(name).name != name or PureWindowsPath(name).name != name
            or not name.endswith(".onnx")):
        raise ValueError(f"onnx_file {name!r}: expected a plain file name ending in .onnx inside the bundle folder")
