"""One guard for every verb that writes: inputs are never destroyed, outputs are replaced
only with ``--force``, special files are refused before they are opened.

Every command that reads inputs and writes an output (``export``, ``quantize``, ``compress``,
``calibrate-force``, ``calibrate-depth``, ``demo``, ``run --out``, ``synth``) calls
:func:`check_output` before any work, with every path it reads. The rules:

* paths are compared resolved (symbolic links and ``..`` followed, :func:`os.path.realpath`);
* an output that *is* an input, lies *inside* an input, or *contains* an input is refused,
  ``--force`` or not (``--out`` = the presses folder, ``--out`` = the folder holding the
  checkpoint, ``quantize B --out B``);
* a folder or bundle output that is a symbolic link is refused (it would be replaced, not followed);
* an existing output is refused without ``--force`` (an empty folder is not); with ``--force`` a *bundle* output may
  only replace a bundle folder (one holding ``model.json``) or an empty folder, never a
  folder of other files, and a *file* output only a regular file;
* an input that is a FIFO, a socket or a device is refused at once, without opening it
  (opening a FIFO blocks until someone writes to it).

Errors are :class:`OutputRefused` (a :class:`~tactile_force.edge.errors.TactileForceError`:
the CLI exits 2) naming the flag, the path and what was expected. Writing the output itself
in one step (a hidden sibling renamed into place) is :mod:`.atomic`.
"""

from __future__ import annotations

import enum
import os
import stat
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from ..errors import TactileForceError

__all__ = ["InputPath", "OutputKind", "OutputRefused", "check_input", "check_output", "special_file_kind"]


class OutputRefused(TactileForceError):
    """An output would destroy an input, replace something without ``--force``, or an input
    is a special file."""


class OutputKind(str, enum.Enum):
    """What an output path is: a bundle folder, another folder, or a single file."""

    BUNDLE = "bundle"
    FOLDER = "folder"
    FILE = "file"


@dataclass(frozen=True, slots=True)
class InputPath:
    """An input of a verb: the flag (or argument name) that gave it and its path."""

    flag: str
    path: str | os.PathLike


def special_file_kind(path: str | os.PathLike) -> str | None:
    """'FIFO', 'socket', 'character device' or 'block device' when ``path`` is one (after
    following links), else None (also for a path that does not exist). Never opens it."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISFIFO(mode):
        return "FIFO"
    if stat.S_ISSOCK(mode):
        return "socket"
    if stat.S_ISCHR(mode):
        return "character device"
    if stat.S_ISBLK(mode):
        return "block device"
    return None


def check_input(path: str | os.PathLike, flag: str, want: str = "a regular file or folder") -> Path:
    """``path`` as a Path; OutputRefused when it is a FIFO, socket or device (a read would
    block or never end). Missing paths pass: the reader reports them.

    Parameters
    ----------
    path : the input path.
    flag : the flag or argument that gave it, for the message.
    want : what was expected, for the message.

    Returns
    -------
    Path : ``path``.
    """
    kind = special_file_kind(path)
    if kind is not None:
        raise OutputRefused(f"{flag} {path}: is a {kind}; expected {want} (special files are refused: "
                            "reading one can block forever)")
    return Path(path)


def _real(p: str | os.PathLike) -> Path:
    return Path(os.path.realpath(os.path.abspath(os.fspath(p))))


def _within(inner: Path, outer: Path) -> bool:
    return inner == outer or outer in inner.parents


def check_output(out: str | os.PathLike, inputs: Iterable[InputPath | tuple[str, str | os.PathLike | None]],
                 *, force: bool = False, kind: OutputKind = OutputKind.FILE, flag: str = "--out",
                 allow_existing: bool = False, verb: str | None = None) -> Path:
    """Refuse an output that would destroy an input or replace something unasked.

    Parameters
    ----------
    out : the output path (a bundle folder, a folder or a file; see ``kind``).
    inputs : every path the verb reads, as InputPath or (flag, path) pairs; None paths are skipped.
    force : the user passed ``--force`` (replacing an existing output is allowed).
    kind : what the output is (decides what ``--force`` may replace).
    flag : the flag that gave ``out``, for messages.
    allow_existing : the verb adds to an existing output itself (``compress`` resumes from its
        ``--out``): an existing folder is not refused, inputs still are.
    verb : the command that writes a *folder* of results (``bench``, ``study``, ...): with
        ``--force`` an existing folder is replaced only when its record proves every entry is
        that verb's own earlier result (:func:`~tactile_force.edge.files.record.verify`; the
        verbs leave this to :func:`~tactile_force.edge.files.atomic.staged_folder`, which
        checks it under the output's claim).

    Returns
    -------
    Path : ``out`` as given (not resolved).

    Raises
    ------
    OutputRefused : naming ``flag``, the path and what was expected.
    """
    given = Path(out)
    real_out = _real(given)
    for item in inputs:
        in_flag, in_path = (item.flag, item.path) if isinstance(item, InputPath) else item
        if in_path is None:
            continue
        check_input(in_path, in_flag)
        real_in = _real(in_path)
        if real_out == real_in:
            raise OutputRefused(f"{flag} {given}: is the input {in_flag} {in_path}; inputs are never replaced "
                                "(--force included): expected a new path")
        if _within(real_in, real_out):
            raise OutputRefused(f"{flag} {given}: holds the input {in_flag} {in_path}; writing it would replace the "
                                "input (--force included): expected a path outside every input")
        if _within(real_out, real_in) and real_in.is_dir():
            raise OutputRefused(f"{flag} {given}: is inside the input {in_flag} {in_path}; inputs are never "
                                "changed: expected a path outside every input")
    if kind is not OutputKind.FILE and not allow_existing and given.is_symlink():
        raise OutputRefused(f"{flag} {given}: is a symbolic link (to {os.readlink(given)}); a {kind.value} is never "
                            f"written through a link nor replaces one: give the folder itself "
                            f"({os.path.realpath(given)}) or a new path")
    kind_now = special_file_kind(given)
    if kind_now is not None:
        raise OutputRefused(f"{flag} {given}: is a {kind_now}; expected a new {kind.value} path")
    if not os.path.lexists(given):
        return given
    if kind is OutputKind.FILE:
        if given.is_dir():
            raise OutputRefused(f"{flag} {given}: is a folder; expected a file path")
        if not force:
            raise OutputRefused(f"{flag} {given}: already exists; pass --force to replace it, or give a new file name")
        return given
    if not given.is_dir():
        what = "an output folder" if kind is OutputKind.FOLDER else "a bundle folder to create"
        raise OutputRefused(f"{flag} {given}: is a file; expected {what}")
    if allow_existing or not any(given.iterdir()):  # an empty folder holds nothing to lose
        return given
    if not force:
        raise OutputRefused(f"{flag} {given}: already exists; pass --force to replace it, or give a new folder")
    if verb is not None:
        from .record import verify

        v = verify(given, verb)
        if not v.proved:
            raise OutputRefused(f"{flag} {given}: holds what 'tactile-force {verb}' cannot prove it wrote: "
                                f"{v.describe()}; --force deletes only an earlier result of the same command whose "
                                "record proves every entry (each file's size and sha256): expected a new folder")
    if kind is OutputKind.BUNDLE:
        entries = [e.name for e in given.iterdir()]
        if entries and "model.json" not in entries:
            raise OutputRefused(f"{flag} {given}: is a folder of other files ({len(entries)} entries, no model.json), "
                                "not a bundle; --force replaces only a bundle folder: expected a new folder")
    return given
