"""Claiming an output before any work: one run per output path, judged before it starts.

:class:`OutputClaim` is taken by every verb that publishes a result folder before it does any
work, and held until the folder is published (or the run ends):

- what can be judged before the work is judged first (:func:`preflight`): ``--out`` a symbolic
  link (refused: a result folder is never written through a link, nor is the link replaced),
  a mount point (a folder cannot be renamed onto it), a parent that is not a writable folder or
  lies on a read-only file system, less free space than the expected size;
- an exclusive lock (``fcntl.flock``) on ``.NAME.tactile-force-claim`` beside the output: a
  second run into the same output is refused at once, naming the running one (the kernel drops
  the lock of a killed run, so a ``kill -9`` never leaves the output locked). A folder a verb
  adds to (``record``, ``compress`` resuming) is only locked, by :data:`CLAIM_INSIDE` in it;
- leftovers of a killed run beside the output are cleaned up under the lock
  (:func:`clean_leftovers`): a staging folder carrying this package's staging mark is removed,
  an earlier result caught between two renames is put back (or removed where its record proves
  every entry); anything else is left alone.

Every failure is :class:`~tactile_force.edge.files.guard.OutputRefused` naming the flag and the
user's path (never the hidden lock or staging name alone).
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import shutil
import socket
import sys
import time
from pathlib import Path

from .guard import OutputRefused

__all__ = ["CLAIM_INSIDE", "STAGING_MARK", "OutputBusy", "OutputClaim", "clean_leftovers", "preflight"]

#: the file inside a staging folder that says this package made it (removed before publishing)
STAGING_MARK = ".tactile-force-staging"
#: the claim file inside a folder a verb adds to (``record``, ``compress``), while it runs
CLAIM_INSIDE = ".tactile-force-claim"


class OutputBusy(OutputRefused):
    """Another run holds the output's claim."""


def _lock_path(dest: Path) -> Path:
    return dest.with_name(f".{dest.name}.tactile-force-claim")


def _mb(n: float) -> str:
    return f"{n / 1e6:.1f} MB"


def _existing_ancestor(p: Path) -> Path:
    for q in (p, *p.parents):
        if os.path.lexists(q):
            return q
    return Path(".")


def preflight(dest: str | os.PathLike, flag: str = "--out", expected_bytes: int | None = None) -> None:
    """Refuse, before any work, an output folder that cannot be published.

    Parameters
    ----------
    dest : the result folder.
    flag : the flag that gave it, for messages.
    expected_bytes : about how many bytes the result will take (None: unknown, not checked).

    Raises
    ------
    OutputRefused : naming ``flag`` and ``dest``.
    """
    d = Path(dest)
    if d.is_symlink():
        target = os.readlink(d)
        raise OutputRefused(f"{flag} {d}: is a symbolic link (to {target}); a result folder is never written "
                            f"through a link nor replaces one: give the folder itself ({os.path.realpath(d)}) or a "
                            "new path")
    if os.path.lexists(d) and os.path.ismount(d):
        raise OutputRefused(f"{flag} {d}: is a mount point; a result folder is published by renaming a finished "
                            "folder into its place, which a mount point cannot take: give a folder inside it")
    parent = Path(os.path.abspath(d)).parent
    anc = _existing_ancestor(parent)
    if not anc.is_dir():
        raise OutputRefused(f"{flag} {d}: {anc} is not a folder; expected a path inside a writable folder")
    try:
        fs = os.statvfs(anc)
    except OSError as exc:
        raise OutputRefused(f"{flag} {d}: cannot inspect {anc} ({exc.strerror or exc})") from None
    if fs.f_flag & getattr(os, "ST_RDONLY", 1):
        raise OutputRefused(f"{flag} {d}: {anc} is on a read-only file system; expected a writable folder")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise OutputRefused(f"{flag} {d}: {anc} is not a writable folder (permission denied); expected a folder "
                            "you may write in")
    if expected_bytes is not None and expected_bytes > 0:
        free = fs.f_bavail * fs.f_frsize
        if free < expected_bytes:
            raise OutputRefused(f"{flag} {d}: the result needs about {_mb(expected_bytes)} and the file system "
                                f"holding {anc} has {_mb(free)} free; free some space or give a folder elsewhere")


def _holder(lock: Path) -> str:
    try:
        info = json.loads(lock.read_text())
        return (f"'tactile-force {info.get('verb')}' (pid {info.get('pid')} on {info.get('host')}, "
                f"since {info.get('started')})")
    except (OSError, ValueError, AttributeError):
        return "another tactile-force run"


def clean_leftovers(dest: str | os.PathLike, verb: str | None = None) -> list[str]:
    """Remove what a killed run left beside ``dest``; call only while holding its claim.

    A hidden sibling ``.NAME.*.partial`` / ``.NAME.*.old`` folder is removed when it carries
    :data:`STAGING_MARK` (a killed run's staging: no live run holds the claim). An earlier result
    caught mid-swap (its record proves every entry) goes back to ``dest`` when ``dest`` is
    missing, else is removed entry by proved entry. Everything else is left alone.

    Returns
    -------
    list[str] : what was done, one line each (for a note on stderr).
    """
    from .record import OUTPUT_MARK, remove_proved, verify

    d = Path(dest)
    done: list[str] = []
    prefix = f".{d.name}."
    try:
        siblings = sorted(d.parent.iterdir())
    except OSError:
        return done
    for p in siblings:
        if not (p.name.startswith(prefix) and p.name.endswith((".partial", ".old"))):
            continue
        if p.is_symlink() or not p.is_dir():
            continue
        if (p / STAGING_MARK).is_file():
            shutil.rmtree(p, ignore_errors=True)
            done.append(f"removed {p.name} (the staging folder of a run that was killed)")
            continue
        if verb is None or not (p / OUTPUT_MARK).is_file():
            continue
        v = verify(p, verb)
        if not v.proved or not v.has_record:
            continue
        if not os.path.lexists(d) and p.name.endswith(".old"):
            os.rename(p, d)
            done.append(f"put back {d.name} (an earlier result a killed run had moved aside as {p.name})")
        elif not remove_proved(p, v):
            done.append(f"removed {p.name} (an earlier result a killed run had swapped out)")
    return done


class OutputClaim:
    """The exclusive claim on one output path, held from before the work until publishing.

    Use as a context manager; :meth:`acquire` runs :func:`preflight`, creates missing parent
    folders (removed again on release when the run left them empty), takes the lock and cleans
    a killed run's leftovers.
    """

    def __init__(self, dest: str | os.PathLike, verb: str, flag: str = "--out",
                 expected_bytes: int | None = None, inside: bool = False) -> None:
        self.dest = Path(dest)
        self.verb = verb
        self.flag = flag
        self.expected_bytes = expected_bytes
        self.inside = inside
        self.id = secrets.token_hex(6)
        self.lock = (Path(os.path.abspath(self.dest)) / CLAIM_INSIDE if inside
                     else _lock_path(Path(os.path.abspath(self.dest))))
        self._fd: int | None = None
        self._made: list[Path] = []

    def _refuse(self, what: str, exc: OSError) -> OutputRefused:
        return OutputRefused(f"{self.flag} {self.dest}: cannot {what} ({exc.strerror or exc})")

    def acquire(self) -> OutputClaim:
        """Judge the output, take the lock, clean leftovers; OutputRefused / OutputBusy otherwise.
        ``inside``: a folder a verb adds to (``record``, ``compress``): only the lock, kept in it."""
        if self.inside:
            self._made = [] if self.dest.is_dir() else [self.dest]  # an empty folder it made goes on release
            try:
                self.dest.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise self._refuse("create it", exc) from None
            try:
                self._lock()
            except BaseException:
                self._undo_parents()
                raise
            return self
        preflight(self.dest, self.flag, self.expected_bytes)
        parent = self.lock.parent
        missing = [q for q in (parent, *parent.parents) if not os.path.lexists(q)]
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise self._refuse(f"create its parent folder {parent}", exc) from None
        self._made = missing  # deepest first
        try:
            self._lock()
        except BaseException:
            self._undo_parents()
            raise
        for line in clean_leftovers(self.dest, self.verb):
            print(f"tactile-force {self.verb}: {self.flag} {self.dest}: {line}", file=sys.stderr)
        return self

    def _lock(self) -> None:
        import fcntl

        for _ in range(5):
            try:
                fd = os.open(self.lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0)
                             | getattr(os, "O_CLOEXEC", 0), 0o644)
            except OSError as exc:
                raise self._refuse(f"create its claim file {self.lock.name} beside it", exc) from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise OutputBusy(f"{self.flag} {self.dest}: {_holder(self.lock)} is writing it now; wait for it to "
                                 "end or give another folder") from None
            except OSError as exc:
                os.close(fd)
                raise self._refuse("lock it", exc) from None
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(self.lock, follow_symlinks=False))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)  # the file was removed by the run that held it: take the new one
        else:
            raise OutputBusy(f"{self.flag} {self.dest}: its claim file {self.lock.name} keeps changing; another "
                             "run is starting there")
        self._fd = fd
        info = {"verb": self.verb, "pid": os.getpid(), "host": socket.gethostname(), "id": self.id,
                "started": time.strftime("%Y-%m-%d %H:%M:%S")}
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)

    def _undo_parents(self) -> None:
        for q in self._made:
            with contextlib.suppress(OSError):
                q.rmdir()
        self._made = []

    def release(self, published: bool) -> None:
        """Drop the claim (remove the claim file); ``published`` False: remove parent folders this
        claim created when they are still empty."""
        if self._fd is None:
            return
        try:
            if os.path.samestat(os.fstat(self._fd), os.stat(self.lock, follow_symlinks=False)):
                os.unlink(self.lock)
        except OSError:
            pass
        finally:
            os.close(self._fd)
            self._fd = None
        if not published or self.inside:
            self._undo_parents()

    def __enter__(self) -> OutputClaim:
        return self.acquire()

    def __exit__(self, exc_type: object, *rest: object) -> None:
        self.release(published=exc_type is None)
