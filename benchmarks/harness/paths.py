"""Where the benchmarks find the repository, their cache and the shared sensor data: one place.

- :func:`repo_root`: the clone's root when the package runs from a clone (``python -m
  benchmarks`` in the repository), None when it is installed (``tactile_force.benchmarks``
  in site-packages has no repository beside it).
- :func:`require_repo`: the same, or a :class:`SetupError` naming what needs a clone
  (writing the repository's docs pages, the robustness suite's worker scripts).
- :func:`cache_dir`: ``$TACTILE_FORCE_CACHE``; else benchmarks/cache in a clone; else
  ``$XDG_CACHE_HOME/tactile_force/benchmarks`` (default ``~/.cache``).
- :func:`shared_data`: ``$TACTILE_FORCE_SHARED_DATA``; else ``shared/data`` beside the clone
  (the real sensor recordings, described by the README in that folder).
- :func:`source_commit`: the commit the code that measures runs at, for a page's header.
- :func:`write_record_and_page`: a page and its JSON record, each written whole.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from tactile_force.edge.errors import TactileForceError

CACHE_ENV = "TACTILE_FORCE_CACHE"
SHARED_DATA_ENV = "TACTILE_FORCE_SHARED_DATA"
#: The code folders whose uncommitted changes a page's commit line mentions.
CODE_DIRS = ("edge", "export", "firmware_bridge", "benchmarks")


class SetupError(TactileForceError):
    """Something the benchmarks need is not where they look: a clone of the repository, or
    the shared sensor data; the message names it and how to provide it."""


def repo_root() -> Path | None:
    """The root of the clone this package runs from, or None when it is installed.

    A clone is recognised by its layout: ``pyproject.toml``, ``edge/`` and ``benchmarks/``
    beside each other, two folders above this file."""
    root = Path(__file__).resolve().parents[2]
    if (root / "pyproject.toml").is_file() and (root / "edge").is_dir() and (root / "benchmarks").is_dir():
        return root
    return None


def require_repo(what: str) -> Path:
    """:func:`repo_root`, or a :class:`SetupError` saying that ``what`` needs a clone."""
    root = repo_root()
    if root is None:
        raise SetupError(f"{what} needs a clone of the repository (run `python -m benchmarks ...` in it); this "
                         f"package is installed at {Path(__file__).resolve().parents[1]}")
    return root


def cache_dir() -> Path:
    """Where rendered frames, datasets and built bundles are kept (made on first use)."""
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    root = repo_root()
    if root is not None:
        return root / "benchmarks" / "cache"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "tactile_force" / "benchmarks"


def shared_data(*parts: str) -> Path:
    """A path in the shared sensor data (``shared_data("aurova_digit_grasp")``).

    Raises
    ------
    SetupError
        The package is installed and ``$TACTILE_FORCE_SHARED_DATA`` is not set (there is no
        clone to find the data beside).
    """
    env = os.environ.get(SHARED_DATA_ENV)
    if env:
        base = Path(env).expanduser()
    else:
        root = repo_root()
        if root is None:
            raise SetupError(f"the shared sensor data: set ${SHARED_DATA_ENV} to its folder (an installed package "
                             "has no clone to find it beside)")
        base = root.parent / "shared" / "data"
    return base.joinpath(*parts)


def source_commit() -> str:
    """The short commit of the clone's HEAD, with a note when code folders have uncommitted
    changes; for an installed package, its version (there is no commit to name)."""
    root = repo_root()
    if root is None:
        from importlib.metadata import PackageNotFoundError, version

        try:
            return f"none (installed tactile-force {version('tactile-force')})"
        except PackageNotFoundError:
            return "none (installed package)"
    try:
        sha = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=10, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no", "--",
                                *CODE_DIRS], capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown (git could not read the clone)"
    return f"{sha} with uncommitted changes to the code" if dirty else sha


def write_record_and_page(out: Path, stem: str, record_json: str, page_md: str) -> Path:
    """``stem``.json then ``stem``.md into the folder ``out`` (made if missing), each written whole
    (staged, then renamed into place); returns the page's path."""
    from tactile_force.edge.files.atomic import staged_file

    out.mkdir(parents=True, exist_ok=True)
    for name, text in ((f"{stem}.json", record_json), (f"{stem}.md", page_md)):
        with staged_file(out / name) as tmp:
            tmp.write_text(text)
    return out / f"{stem}.md"
