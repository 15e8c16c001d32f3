"""The record in a result folder: what a verb wrote there, as proof.

A verb that publishes a folder of results (``bench``, ``study``, ``synth``, ``demo``) leaves
:data:`OUTPUT_MARK` in it: the verb, a random id, the folder's own identity (``st_dev`` and
``st_ino``: a rename keeps them, a copy does not) and, for every file it wrote, its size and
sha256 (every folder by name, every symbolic link by its target). ``--force`` may delete an
entry only when this record proves it (:func:`verify`): a regular file of the recorded size and
hash, a recorded folder, a recorded link with its target. Anything else (a file the user added
or edited, a link or a folder the user put there, a record copied from another folder, a record
of an earlier version that lists names only) is *unproved*: it is kept, and ``--force`` refuses
naming it.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
import stat
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["OUTPUT_MARK", "RECORD_FORMAT", "Verification", "remove_proved", "sha256_of", "verify", "write_record"]

#: the record in every published result folder (JSON; see the module docstring)
OUTPUT_MARK = ".tactile-force-output.json"
#: the record's format: 2 = sizes, hashes and the folder's identity (1 listed names only)
RECORD_FORMAT = 2

#: what a file looked like when it was proved: (st_ino, st_size, st_mtime_ns, st_ctime_ns)
StatKey = tuple[int, int, int, int]


def _key(st: os.stat_result) -> StatKey:
    return (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


def sha256_of(path: str | os.PathLike, chunk: int = 1 << 20) -> str:
    """Hex sha256 of a file's bytes (never follows a link: the caller checked it is a regular file)."""
    h = hashlib.sha256()
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0))
    with os.fdopen(fd, "rb") as fh:
        while block := fh.read(chunk):
            h.update(block)
    return h.hexdigest()


def _walk(root: Path, exclude: tuple[str, ...] = ()) -> list[tuple[str, os.stat_result]]:
    """(relative path, lstat) of every entry under ``root``, parents before children, links not
    followed; the record itself (and ``exclude``, top-level names) left out."""
    out: list[tuple[str, os.stat_result]] = []
    stack = [""]
    while stack:
        rel_dir = stack.pop()
        with os.scandir(root / rel_dir if rel_dir else root) as it:
            entries = sorted(it, key=lambda e: e.name)
        for e in entries:
            rel = f"{rel_dir}/{e.name}" if rel_dir else e.name
            if rel == OUTPUT_MARK or rel in exclude:
                continue
            st = e.stat(follow_symlinks=False)
            out.append((rel, st))
            if stat.S_ISDIR(st.st_mode):
                stack.append(rel)
    return out


def write_record(folder: str | os.PathLike, verb: str, exclude: tuple[str, ...] = ()) -> dict:
    """Write :data:`OUTPUT_MARK` into ``folder`` listing everything in it (fsync'd) and return it.

    Parameters
    ----------
    folder : the finished staging folder (its identity is the published folder's: a rename keeps it).
    verb : the command that wrote it.
    exclude : top-level names left out of the record (the staging mark, removed before publishing).
    """
    root = Path(folder)
    files: dict[str, dict[str, int | str]] = {}
    folders: list[str] = []
    links: dict[str, str] = {}
    for rel, st in _walk(root, exclude):
        if stat.S_ISDIR(st.st_mode):
            folders.append(rel)
        elif stat.S_ISLNK(st.st_mode):
            links[rel] = os.readlink(root / rel)
        elif stat.S_ISREG(st.st_mode):
            files[rel] = {"size": st.st_size, "sha256": sha256_of(root / rel)}
    me = os.stat(root)
    record = {"format": RECORD_FORMAT, "verb": verb, "id": secrets.token_hex(8),
              "folder": {"st_dev": me.st_dev, "st_ino": me.st_ino},
              "files": files, "folders": sorted(folders), "links": links}
    fd = os.open(root / OUTPUT_MARK, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
    with os.fdopen(fd, "w") as fh:
        fh.write(json.dumps(record, indent=1) + "\n")
        fh.flush()
        os.fsync(fh.fileno())
    return record


@dataclass
class Verification:
    """What :func:`verify` found in a folder.

    Attributes
    ----------
    unproved : (relative path, why) of every entry the record does not prove, in walk order.
    files : relative path -> how each proved file looked when it was proved (for
        :func:`remove_proved` and a later :func:`verify`, which re-hashes only what changed).
    folders : the proved folders, children before parents.
    links : the proved links.
    has_record : the folder holds a readable record of the verb.
    empty : the folder holds nothing at all (no record either).
    """

    unproved: list[tuple[str, str]] = field(default_factory=list)
    files: dict[str, StatKey] = field(default_factory=dict)
    folders: list[str] = field(default_factory=list)
    links: list[str] = field(default_factory=list)
    has_record: bool = False
    empty: bool = True

    @property
    def proved(self) -> bool:
        """Every entry is proved (an empty folder included)."""
        return not self.unproved

    def describe(self, limit: int = 3) -> str:
        """The first few unproved entries with the reason, for a message."""
        shown = "; ".join(f"{rel} ({why})" for rel, why in self.unproved[:limit])
        more = len(self.unproved) - limit
        return shown + (f"; and {more} more" if more > 0 else "")


def _load(root: Path, verb: str) -> tuple[dict | None, str]:
    """(the record, '') when it is a readable format-2 record of ``verb`` made for this very
    folder, else (None, why every entry is unproved)."""
    try:
        raw = json.loads((root / OUTPUT_MARK).read_text())
    except FileNotFoundError:
        return None, f"no record of 'tactile-force {verb}' in the folder"
    except (OSError, ValueError) as exc:
        return None, f"its record {OUTPUT_MARK} is unreadable ({exc})"
    if not isinstance(raw, dict) or raw.get("verb") != verb:
        made_by = raw.get("verb") if isinstance(raw, dict) else None
        return None, f"the folder is a result of 'tactile-force {made_by}', not of '{verb}'" if made_by else \
            f"its record {OUTPUT_MARK} is not a record of 'tactile-force {verb}'"
    if raw.get("format") != RECORD_FORMAT:
        return None, ("its record lists names only (an earlier version's record): it proves nothing; "
                      "delete the folder yourself if it is yours to lose")
    try:
        ident = raw["folder"]
        me = os.stat(root)
        if (int(ident["st_dev"]), int(ident["st_ino"])) != (me.st_dev, me.st_ino):
            return None, ("its record was made for another folder (a copy or a restored folder): it proves "
                          "nothing here")
        if not (isinstance(raw["files"], dict) and isinstance(raw["folders"], list)
                and isinstance(raw.get("links", {}), dict)):
            raise TypeError("files, folders or links")
    except (KeyError, TypeError, ValueError, OSError) as exc:
        return None, f"its record {OUTPUT_MARK} is malformed ({exc})"
    return raw, ""


def verify(folder: str | os.PathLike, verb: str, known: Verification | None = None) -> Verification:
    """Which entries of ``folder`` its record proves ``verb`` wrote.

    Parameters
    ----------
    folder : the result folder (links inside are never followed).
    verb : the command whose earlier result it should be.
    known : an earlier verification of the same folder: a file whose inode, size, mtime and ctime
        are unchanged since then is not hashed again (any write changes its ctime).

    Returns
    -------
    Verification : the unproved entries with the reason, and how each proved file looked.
    """
    root = Path(folder)
    v = Verification()
    entries = _walk(root)
    v.has_record = os.path.lexists(root / OUTPUT_MARK)
    v.empty = not entries and not v.has_record
    record, why_none = _load(root, verb)
    v.has_record = record is not None
    if record is None:
        v.unproved = [(rel, why_none) for rel, _ in entries]
        if not entries and os.path.lexists(root / OUTPUT_MARK):
            v.unproved = [(OUTPUT_MARK, why_none)]
        return v
    files, folders, links = record["files"], set(record["folders"]), record.get("links", {})
    for rel, st in entries:
        mode = st.st_mode
        if stat.S_ISDIR(mode):
            if rel in folders:
                v.folders.append(rel)
            else:
                v.unproved.append((rel, f"a folder 'tactile-force {verb}' did not make"))
        elif stat.S_ISLNK(mode):
            if rel in links and os.readlink(root / rel) == links[rel]:
                v.links.append(rel)
            else:
                v.unproved.append((rel, f"a symbolic link 'tactile-force {verb}' did not make"))
        elif not stat.S_ISREG(mode):
            v.unproved.append((rel, "a special file"))
        elif rel not in files:
            v.unproved.append((rel, f"a file 'tactile-force {verb}' did not write"))
        else:
            want = files[rel]
            key = _key(st)
            if known is not None and known.files.get(rel) == key:
                v.files[rel] = key
            elif not isinstance(want, dict) or st.st_size != want.get("size") \
                    or sha256_of(root / rel) != want.get("sha256"):
                v.unproved.append((rel, f"changed since 'tactile-force {verb}' wrote it"))
            else:
                v.files[rel] = key
    v.folders.reverse()  # children before parents, for removal
    return v


def remove_proved(folder: str | os.PathLike, v: Verification) -> list[str]:
    """Delete what ``v`` proved in ``folder`` (a file only while it looks as it did when proved),
    then its record and the folder itself when nothing else is left.

    Returns
    -------
    list[str] : the relative paths left in place (nothing when the folder is gone).
    """
    root = Path(folder)
    left: list[str] = [rel for rel, _ in v.unproved]
    for rel, key in v.files.items():
        p = root / rel
        try:
            if _key(os.lstat(p)) == key:
                os.unlink(p)
            else:
                left.append(rel)
        except FileNotFoundError:
            pass
    for rel in v.links:
        try:
            os.unlink(root / rel)
        except FileNotFoundError:
            pass
    for rel in v.folders:
        try:
            os.rmdir(root / rel)
        except FileNotFoundError:
            pass
        except OSError:
            left.append(rel)
    if not left:
        try:
            os.unlink(root / OUTPUT_MARK)
        except FileNotFoundError:
            pass
        try:
            os.rmdir(root)
        except FileNotFoundError:
            pass
        except OSError:
            left = [e.name for e in os.scandir(root)]
    return left
