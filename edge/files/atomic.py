"""Publishing an output in one step: a folder or file appears whole, or not at all.

Every verb that writes a folder of results (``bench``, ``study``, ``synth``, ``demo``) enters
:func:`staged_folder` *before* its work: the output is claimed (:mod:`.claim`: judged, locked
against a second run, a killed run's leftovers cleaned), checked (:func:`~.guard.check_output`;
with ``--force`` an existing folder must be proved by its record, :mod:`.record`) and a hidden
sibling ``.NAME.XXXX.partial`` is made to write into. When the work is done:

- the staging folder gets its record (every file's size and sha256, the folder's identity);
- a new ``NAME`` appears by one ``rename`` that never replaces anything (``RENAME_NOREPLACE``);
- an existing ``NAME`` is swapped with the new one by one ``renameat2(RENAME_EXCHANGE)``
  (Linux), else by two renames, and then *verified again*: what appeared or changed in it while
  the verb ran is never deleted: the swap is undone, nothing is replaced, and the verb fails
  naming the entry. Otherwise the old folder is removed entry by entry, each only while it is
  what the record proves;
- an interrupted or failed run removes its staging folder and leaves ``NAME`` as it was: the
  previous result or nothing, never a half folder that looks finished. An OS error while writing
  names the user's path (``--out NAME/...``), never only the hidden staging name.

Single files (``--save-scene``, reports, CSV caches) use :func:`staged_file`.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import shutil
import signal
import sys
import tempfile
import threading
from collections.abc import Iterable, Iterator
from pathlib import Path

from ..errors import TactileForceError
from ..interrupts import raise_pending
from .record import OUTPUT_MARK, Verification, remove_proved, verify, write_record

__all__ = ["OUTPUT_MARK", "exchange", "foreign_files", "fsync_dir", "publish_folder", "rename_noreplace",
           "staged_file", "staged_folder"]

_AT_FDCWD = -100
_RENAME_NOREPLACE = 1
_RENAME_EXCHANGE = 2
#: OS errors that are about the output's file system, not about one input: named by the output's path
_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EFBIG}


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


def _renameat2(a: Path, b: Path, flags: int) -> bool:
    """``renameat2(a, b, flags)``; False where the call or the flag is unsupported, OSError naming
    ``b`` on any other failure."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), flags) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def exchange(a: Path, b: Path) -> bool:
    """Atomically swap two existing paths (Linux ``renameat2``); False where unsupported."""
    return _renameat2(a, b, _RENAME_EXCHANGE)


def rename_noreplace(a: Path, b: Path) -> bool:
    """Rename ``a`` to ``b`` only if ``b`` does not exist; False when ``b`` exists (appeared).

    ``renameat2(RENAME_NOREPLACE)`` where supported, else a check and a ``rename`` (which on
    Linux would replace an empty folder that appeared between the two)."""
    try:
        if _renameat2(a, b, _RENAME_NOREPLACE):
            return True
    except FileExistsError:
        return False
    except OSError as exc:
        if exc.errno in (errno.EEXIST, errno.ENOTEMPTY):
            return False
        raise
    if os.path.lexists(b):
        return False
    os.rename(a, b)
    return True


def foreign_files(folder: str | os.PathLike, verb: str) -> list[str]:
    """Entries of ``folder`` (relative paths) its record does not prove ``verb`` wrote: added,
    edited or of another verb (:func:`~.record.verify`). An empty list: ``--force`` may replace it."""
    return [rel for rel, _ in verify(folder, verb).unproved]


def _named(exc: OSError, staging: Path, dest: Path) -> OSError:
    """``exc`` naming the user's path instead of the hidden staging one (``exc`` itself when it is
    about another path, an input)."""
    fn = exc.filename
    t = os.fspath(staging)
    if fn is not None:
        s = os.fsdecode(fn)
        if s != t and not s.startswith(t + os.sep):
            return exc
        path = os.fspath(dest) + s[len(t):]
    elif exc.errno in _WRITE_ERRNOS:
        path = os.fspath(dest)
    else:
        return exc
    what = exc.strerror or str(exc)
    return OSError(exc.errno, f"{what} (while writing the result; nothing was published, what was there "
                              "before is kept)", path)


class _Refused(TactileForceError):
    """Publishing found something it may not replace (carries the message)."""


def publish_folder(tmp: Path, dest: Path, verb: str, *, force: bool = False, known: Verification | None = None,
                   flag: str = "--out") -> list[str]:
    """Move the complete folder ``tmp`` (with its record) to ``dest`` in one step.

    A new ``dest`` appears by a rename that never replaces. An existing ``dest`` is swapped with
    ``tmp`` (exchange, else two renames) and verified again: it may go only when it is empty, or
    with ``force`` when its record proves every entry; else the swap is undone and
    :class:`~.guard.OutputRefused` names the first entries. The old folder is removed entry by
    proved entry; if something appeared in the instant between, the rest is kept as
    ``NAME.kept-XXXX`` beside it (named on stderr).

    Returns
    -------
    list[str] : what was kept beside ``dest`` (empty normally).
    """
    raise_pending()  # a signal a library swallowed while the result was made: the result is not published
    fsync_dir(tmp)
    kept: list[str] = []
    with _signals_held():  # a Ctrl-C in here would leave the earlier folder half-removed at a hidden path
        old, v = _swap_in(tmp, dest, verb, force, known, flag)
        if old is None:
            return kept
        if remove_proved(old, v):
            keep = dest.with_name(f"{dest.name}.kept-{os.urandom(3).hex()}")
            os.rename(old, keep)
            kept.append(str(keep))
            print(f"tactile-force {verb}: {flag} {dest}: something appeared in the earlier result while it was being "
                  f"replaced; kept as {keep}", file=sys.stderr)
        fsync_dir(dest.parent)
    return kept


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM wait until the block ends (main thread; elsewhere nothing changes),
    then reach their handler as they would have."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    held = (int(signal.SIGINT), int(signal.SIGTERM))
    old: dict[int, object] = {sig: signal.signal(sig, lambda signum, frame: got.append(signum)) for sig in held}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]
        if got:
            handler = old[got[0]]
            if callable(handler):
                handler(got[0], None)
            elif handler == signal.SIG_DFL:
                if got[0] == signal.SIGINT:
                    raise KeyboardInterrupt
                os.kill(os.getpid(), got[0])


def _swap_in(tmp: Path, dest: Path, verb: str, force: bool, known: Verification | None,
             flag: str) -> tuple[Path | None, Verification]:
    """Put ``tmp`` in place as ``dest``; (where the earlier folder now is, its verification),
    (None, ...) when ``dest`` was new. Undone on refusal (OutputRefused) or any error."""
    from .guard import OutputRefused

    if not os.path.lexists(dest) and rename_noreplace(tmp, dest):
        fsync_dir(dest.parent)
        return None, Verification()
    if dest.is_symlink() or not dest.is_dir():
        raise OutputRefused(f"{flag} {dest}: {'a symbolic link' if dest.is_symlink() else 'a file'} appeared there "
                            f"while 'tactile-force {verb}' ran; nothing was replaced and the new result was discarded")
    swapped = exchange(tmp, dest)
    old = tmp if swapped else dest.with_name(f".{dest.name}.{os.urandom(4).hex()}.old")
    if not swapped:
        os.rename(dest, old)

    def undo() -> None:
        if swapped:
            exchange(tmp, dest)
        else:
            os.rename(old, dest)

    try:
        v = verify(old, verb, known)
    except BaseException:
        undo()
        raise
    if not (v.empty or (force and v.proved and v.has_record)):
        undo()
        if force:
            raise OutputRefused(f"{flag} {dest}: holds what 'tactile-force {verb}' cannot prove it wrote: "
                                f"{v.describe()} (it appeared or changed while the verb ran); nothing was replaced or "
                                "deleted and the new result was discarded")
        raise OutputRefused(f"{flag} {dest}: appeared while 'tactile-force {verb}' ran and is not empty; nothing was "
                            "replaced and the new result was discarded (pass --force to replace an earlier result of "
                            "the same command)")
    if not swapped and not rename_noreplace(tmp, dest):
        keep = dest.with_name(f"{dest.name}.kept-{os.urandom(3).hex()}")
        os.rename(old, keep)
        raise OutputRefused(f"{flag} {dest}: appeared again while its earlier content was moved aside (kept as "
                            f"{keep}); nothing was deleted and the new result was discarded")
    return old, v


def _refuse_unproved(dest: Path, verb: str, flag: str, v: Verification) -> None:
    from .guard import OutputRefused

    raise OutputRefused(f"{flag} {dest}: holds what 'tactile-force {verb}' cannot prove it wrote: {v.describe()}; "
                        "--force deletes only an earlier result of the same command whose record proves every entry "
                        "(each file's size and sha256): expected a new folder, or move these away")


@contextlib.contextmanager
def staged_folder(dest: str | os.PathLike, verb: str, *, force: bool = False,
                  inputs: Iterable[tuple[str, str | os.PathLike | None]] = (), flag: str = "--out",
                  expected_bytes: int | None = None) -> Iterator[Path]:
    """Claim ``dest``, judge it, and yield a hidden sibling to write the result into; publish it
    as ``dest`` when the block ends. Enter it *before* the work: every refusal comes first.

    Parameters
    ----------
    dest : the result folder.
    verb : the command writing it (recorded in :data:`OUTPUT_MARK`; a second run of any verb into
        the same ``dest`` is refused while this one holds it).
    force : the user passed ``--force``: an existing ``dest`` is replaced when its record proves
        every entry (an empty folder needs no ``--force``).
    inputs : (flag, path) of what the verb reads: ``dest`` must not be, hold or lie in any.
    flag : the flag that gave ``dest``, for messages.
    expected_bytes : about how large the result will be (checked against the free space), or None.

    Yields
    ------
    Path : the folder to write into; it becomes ``dest`` when the block ends normally. On any
        exception (``KeyboardInterrupt`` and SIGTERM included) it is removed and ``dest`` is
        left as it was; an OS error names ``dest``.

    Raises
    ------
    OutputRefused : before the block runs (a link, a mount point, read-only, no space, another run,
        an input, exists without ``force``, unproved entries) or at publishing (something appeared).
    """
    from .claim import STAGING_MARK, OutputClaim
    from .guard import OutputKind, OutputRefused, check_output

    dest = Path(dest)
    claim = OutputClaim(dest, verb, flag, expected_bytes).acquire()
    published = False
    tmp: Path | None = None
    staging_ino = -1
    try:
        check_output(dest, inputs, force=force, kind=OutputKind.FOLDER, flag=flag)
        known: Verification | None = None
        if force and dest.is_dir():
            known = verify(dest, verb)
            if not (known.empty or known.proved):
                _refuse_unproved(dest, verb, flag, known)
        try:
            tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.{claim.id}.", suffix=".partial", dir=claim.lock.parent))
            staging_ino = os.stat(tmp).st_ino
            (tmp / STAGING_MARK).write_text(claim.id + "\n")
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o777 & ~umask)  # mkdtemp makes it 0700; a result is readable like any folder
        except OSError as exc:
            raise OutputRefused(f"{flag} {dest}: cannot create its staging folder beside it "
                                f"({exc.strerror or exc})") from None
        try:
            yield tmp
            write_record(tmp, verb, exclude=(STAGING_MARK,))
            os.unlink(tmp / STAGING_MARK)
            publish_folder(tmp, dest, verb, force=force, known=known, flag=flag)
            published = True
        except OSError as exc:
            named = _named(exc, tmp, dest)
            if named is exc:
                raise
            raise named from exc
    finally:
        if tmp is not None and not published and _is(tmp, staging_ino):  # never an earlier result swapped there
            shutil.rmtree(tmp, ignore_errors=True)
        claim.release(published)


def _is(path: Path, ino: int) -> bool:
    try:
        return os.lstat(path).st_ino == ino
    except OSError:
        return False


@contextlib.contextmanager
def staged_file(dest: str | os.PathLike) -> Iterator[Path]:
    """Write one file under a hidden name and rename it to ``dest`` when the block ends.

    Yields
    ------
    Path : the path to write; on an exception it is removed and ``dest`` is left as it was (an
        OS error about the hidden file names ``dest``).
    """
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{dest.name}.", suffix=".partial", dir=dest.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        try:
            yield tmp
            raise_pending()
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)
            os.replace(tmp, dest)
            fsync_dir(dest.parent)
        except OSError as exc:
            named = _named(exc, tmp, dest)
            if named is exc:
                raise
            raise named from exc
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
