"""Publishing an output in one step: a folder or file appears whole, or not at all.

Every verb that writes a folder of results (``bench``, ``study``, ``synth``, ``demo``) or a
single file (``--save-scene``) writes it into a hidden sibling first and moves it into place
when the work is done (:func:`staged_folder`, :func:`staged_file`):

- a new ``NAME`` appears by one ``rename``;
- an existing ``NAME`` (replaced only with ``--force``, checked before any work by
  :func:`~tactile_force.edge.files.guard.check_output`) is swapped with the new one by one
  ``renameat2(RENAME_EXCHANGE)`` (Linux), else by two renames;
- an interrupted or failed run removes its hidden sibling and leaves ``NAME`` as it was: the
  previous result or nothing, never a half folder that looks finished.

A folder a verb publishes carries :data:`OUTPUT_MARK`, a small JSON record of the verb and
every file it wrote. ``--force`` replaces a folder only when that record says the same verb
made it and lists every file in it (:func:`foreign_files`), so a user's own files added to a
result folder are never deleted.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["OUTPUT_MARK", "exchange", "foreign_files", "fsync_dir", "publish_folder", "staged_file",
           "staged_folder"]

#: the record in every published result folder: {"verb": ..., "files": [relative paths]}
OUTPUT_MARK = ".tactile-force-output.json"

_AT_FDCWD = -100
_RENAME_EXCHANGE = 2


def fsync_dir(path: Path) -> None:
    """Flush a folder's entries to disk (best effort: some file systems refuse)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def exchange(a: Path, b: Path) -> bool:
    """Atomically swap two existing paths (Linux ``renameat2``); False where unsupported."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def publish_folder(tmp: Path, dest: Path) -> None:
    """Move the complete folder ``tmp`` to ``dest`` in one step, replacing ``dest`` if it exists.

    ``dest`` is at every instant the old folder or the new one (exchange), or, where the
    exchange is unsupported, briefly absent with the old one kept as ``.NAME.old`` until
    the new one is in place.
    """
    fsync_dir(tmp)
    if not os.path.lexists(dest):
        os.rename(tmp, dest)
    elif exchange(tmp, dest):
        shutil.rmtree(tmp, ignore_errors=True)  # tmp now holds the old folder
    else:
        old = dest.with_name(f".{dest.name}.old")
        shutil.rmtree(old, ignore_errors=True)
        os.replace(dest, old)
        os.replace(tmp, dest)
        shutil.rmtree(old, ignore_errors=True)
    fsync_dir(dest.parent)


def _files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if not p.is_dir() and p.name != OUTPUT_MARK)


def foreign_files(folder: str | os.PathLike, verb: str) -> list[str]:
    """Files in ``folder`` that ``verb`` did not write there (relative paths), per its
    :data:`OUTPUT_MARK`; every file when the folder carries no record of ``verb``. An empty
    list: the folder is ``verb``'s own result (or empty) and ``--force`` may replace it."""
    root = Path(folder)
    found = _files(root)
    try:
        mark = json.loads((root / OUTPUT_MARK).read_text())
        made = set(mark["files"]) if mark.get("verb") == verb else set()
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        made = set()
    return [f for f in found if f not in made]


def _new_sibling(dest: Path, suffix: str) -> Path:
    dest.parent.mkdir(parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=f".{dest.name}.", suffix=suffix, dir=dest.parent))


@contextlib.contextmanager
def staged_folder(dest: str | os.PathLike, verb: str) -> Iterator[Path]:
    """Write a result folder in a hidden sibling and publish it as ``dest`` when the block ends.

    Parameters
    ----------
    dest : the result folder (checked beforehand with ``check_output(..., verb=verb)``).
    verb : the command writing it (recorded in :data:`OUTPUT_MARK`).

    Yields
    ------
    Path : the folder to write into; it becomes ``dest`` when the block ends normally. On any
        exception (``KeyboardInterrupt`` and SIGTERM included) it is removed and ``dest`` is
        left as it was.
    """
    dest = Path(dest)
    tmp = _new_sibling(dest, ".partial")
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it 0700; a result is readable like any folder
    try:
        yield tmp
        (tmp / OUTPUT_MARK).write_text(json.dumps({"verb": verb, "files": _files(tmp)}, indent=1) + "\n")
        publish_folder(tmp, dest)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


@contextlib.contextmanager
def staged_file(dest: str | os.PathLike) -> Iterator[Path]:
    """Write one file under a hidden name and rename it to ``dest`` when the block ends.

    Yields
    ------
    Path : the path to write; on an exception it is removed and ``dest`` is left as it was.
    """
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".partial", dir=dest.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, dest)
        fsync_dir(dest.parent)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
