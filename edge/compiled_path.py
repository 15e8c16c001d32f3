"""Which per-frame path a process runs: OpenCV / numpy, or the compiled kernels of the 'fast' extra.

The contact gate's image work (edge/gate/frame_work.py) and the compact depth bundles' depth stage
(edge/depth/stage.py) each have two equal paths: OpenCV and numpy calls (always there: the robot-side
install), and kernels compiled by numba (edge/gate/kernels.py, edge/depth/kernels.py; the ``fast``
extra) that give the same values bit for bit with fewer instructions. Nothing compiles on the
reading path, nor while a gate, stage or runtime is made: the kernels are compiled ahead of time by
``tactile-force kernels`` (once per environment, about 10 s on 2 cores; a container image runs it at
build time and carries :func:`cache_dir`), and a gate or depth stage takes them from numba's cache
when it is made (:func:`request`). Where they are not in the cache (not compiled yet, or compiled by
another version), the OpenCV / numpy path serves and one line says how to compile them. Readings
are the same on either path.

:class:`KernelMode` (environment variable ``TACTILE_FORCE_KERNELS``, or :func:`set_kernel_mode`):

- ``auto`` (default): with numba installed, the cached kernels (loading them: about 0.6 s, once
  per process); without them (no index in the cache: numba is not even imported), or without
  numba, the OpenCV / numpy path.
- ``off``: the OpenCV / numpy path only; numba is never imported.
- ``compile``: as ``auto``, but kernels missing from the cache are compiled when the gate or stage
  is made, and a line says so (``tactile-force kernels``, the benchmarks that count the compiled
  path, the tests).

Why not compile in the background while OpenCV serves: numba holds the interpreter lock while it
compiles, and readings taken meanwhile stalled for up to 150 ms (p99 55-135 ms per second of the
10 s compile, AMD EPYC 2-core VM; docs/benchmarks/startup.md).

This module does not import numba; importing it costs nothing.
"""

from __future__ import annotations

import enum
import functools
import importlib
import importlib.util
import logging
import os
import sys
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType

from .errors import MissingExtraError, OptionsError

__all__ = ["KIND_MODULES", "KernelMode", "cache_dir", "depth_kernels", "describe", "gate_kernels", "installed",
           "kernel_mode", "load", "loaded_kinds", "request", "set_kernel_mode"]

_log = logging.getLogger(__name__)

#: the environment variable that sets the mode
ENV = "TACTILE_FORCE_KERNELS"
#: kind -> the module of its kernels (each has ``warm()``, which loads or compiles every kernel)
KIND_MODULES = {"gate": "tactile_force.edge.gate.kernels", "depth": "tactile_force.edge.depth.kernels"}


class KernelMode(enum.Enum):
    """When the compiled kernels are used (see the module docstring)."""

    AUTO = "auto"
    OFF = "off"
    COMPILE = "compile"


_mode: KernelMode | None = None  # set_kernel_mode(); None: the environment variable
_lock = threading.Lock()
_loaded: dict[str, ModuleType] = {}  # kind -> its loaded kernels module
_missing: dict[str, str] = {}  # kind -> why its kernels are not used (not cached, failed)


def kernel_mode() -> KernelMode:
    """The mode in force: :func:`set_kernel_mode`'s, else ``TACTILE_FORCE_KERNELS`` (default auto)."""
    if _mode is not None:
        return _mode
    raw = os.environ.get(ENV, "auto").strip().lower() or "auto"
    try:
        return KernelMode(raw)
    except ValueError:
        raise OptionsError(f"{ENV}={os.environ.get(ENV)!r}: expected one of auto, off, compile") from None


def set_kernel_mode(mode: KernelMode | str | None) -> None:
    """Set the mode for this process (``None``: back to ``TACTILE_FORCE_KERNELS``); takes effect for the
    gates and depth stages made afterwards (kernels already loaded stay in use unless ``off``)."""
    global _mode
    if mode is None or isinstance(mode, KernelMode):
        _mode = mode
        return
    try:
        _mode = KernelMode(str(mode).strip().lower())
    except ValueError:
        raise OptionsError(f"kernel mode {mode!r}: expected one of auto, off, compile") from None


@functools.cache
def installed() -> bool:
    """Whether numba (the ``fast`` extra) can be imported here (looked up, not imported)."""
    return importlib.util.find_spec("numba") is not None


def gate_kernels() -> ModuleType | None:
    """The contact gate's kernels where loaded (and the mode not ``off``), else None: the OpenCV path."""
    return _loaded.get("gate") if _mode is not KernelMode.OFF else None


def depth_kernels() -> ModuleType | None:
    """The depth stage's kernels where loaded (and the mode not ``off``), else None: the numpy path."""
    return _loaded.get("depth") if _mode is not KernelMode.OFF else None


def loaded_kinds() -> list[str]:
    """The kinds whose compiled kernels this process has loaded."""
    return list(_loaded)


def request(kind: str) -> None:
    """A gate (``kind`` 'gate') or depth stage ('depth') is being made: take its kernels from numba's
    cache (once per process; in ``compile`` mode compile those missing); nothing in ``off`` mode or
    without numba. Never raises: where they cannot be had, the OpenCV / numpy path serves."""
    mode = kernel_mode()
    if mode is KernelMode.OFF or not installed():
        return
    with _lock:
        if kind in _loaded or (kind in _missing and mode is KernelMode.AUTO):
            return
        if mode is KernelMode.AUTO and not _indexed(kind):  # never compiled here: not even numba is imported
            _not_compiled(kind)
            return
        try:
            _load_one(kind, compile_missing=mode is KernelMode.COMPILE)
        except _NotCompiled:
            _not_compiled(kind)
        except Exception as exc:  # a broken numba install: the readings never depend on it
            _missing[kind] = f"{exc.__class__.__name__}: {exc}"
            _log.warning("the %s's compiled kernels could not load (%s); this process takes the equal "
                         "OpenCV / numpy path", _NAMES[kind], _missing[kind])


_NAMES = {"gate": "contact gate", "depth": "depth stage"}


def _not_compiled(kind: str) -> None:
    """``kind``'s kernels are not in numba's cache: the OpenCV / numpy path serves; one line says how to compile."""
    _missing[kind] = "not compiled for this environment"
    _log.warning("the %s's compiled kernels (numba) are installed but not compiled for this environment; this "
                 "process takes the equal OpenCV / numpy path. Compile them once with: tactile-force kernels",
                 _NAMES[kind])


class _NotCompiled(Exception):
    """A kernel would have been compiled where only loading was allowed."""


def cache_dir() -> str:
    """Where the kernels' compiled forms are kept (a folder; created by numba when first used):
    ``NUMBA_CACHE_DIR`` when set, else ``tactile_force/numba`` in the user's cache folder
    (``XDG_CACHE_HOME``, default ``~/.cache``). Never beside the modules: in an installed package
    that is site-packages, where pip's uninstall leaves the files it did not install, and the
    folders left there without their ``__init__.py`` shadow a later (editable) install of the
    package. A container image carries the compiled kernels by running ``tactile-force kernels``
    at build time with this folder inside the image."""
    numba = sys.modules.get("numba")  # numba reads NUMBA_CACHE_DIR into its config (a user may set that)
    user_set = (getattr(getattr(numba, "config", None), "CACHE_DIR", None) if numba
                else os.environ.get("NUMBA_CACHE_DIR"))
    if user_set:
        return str(user_set)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return str(Path(base) / "tactile_force" / "numba")


def _indexed(kind: str) -> bool:
    """Whether numba's cache folder holds an index of ``kind``'s kernels (numba names its folder after the
    kernels' source folder: gate_*, depth_*); without one nothing can load, and numba need not be
    imported to find that out. An index from another numba or CPU is found out by loading."""
    return any(Path(cache_dir()).glob(f"{kind}_*/kernels.*.nbi"))


def _load_one(kind: str, compile_missing: bool) -> None:
    """Import ``kind``'s kernels and load each from numba's cache for the argument types the package
    passes (their module's ``warm()``); a kernel missing from the cache raises :class:`_NotCompiled`
    unless ``compile_missing`` (then a line says it compiles, and how long it took)."""
    if kind in _loaded:
        return
    module = importlib.import_module(KIND_MODULES[kind])
    from numba.core import event

    class Watch(event.Listener):  # numba's listener: told when a compile begins and ends
        compiled = False

        def on_start(self, ev: object) -> None:
            if not compile_missing:
                raise _NotCompiled(kind)
            if not self.compiled:
                _log.warning("compiling the %s's kernels (numba, once per environment: about 10 s on 2 cores) "
                             "into %s", _NAMES[kind], cache_dir())
            self.compiled = True

        def on_end(self, ev: object) -> None:
            pass

    t0 = time.perf_counter()
    watch = Watch()
    with event.install_listener("numba:compile", watch):
        module.warm()
    _loaded[kind] = module
    _missing.pop(kind, None)
    if watch.compiled:
        _log.warning("the %s's kernels compiled in %.1f s; later runs load them from the cache",
                     _NAMES[kind], time.perf_counter() - t0)


def load(kinds: Iterable[str] = ("gate", "depth")) -> list[str]:
    """Load the kernels of ``kinds`` now, compiling those missing from numba's cache (what
    ``tactile-force kernels`` does); returns the kinds it loaded.

    Raises
    ------
    MissingExtraError
        numba (the ``fast`` extra) is not installed.
    """
    if not installed():
        raise MissingExtraError("numba", "fast", "the compiled kernels")
    kinds = list(kinds)
    for kind in kinds:
        if kind not in KIND_MODULES:
            raise OptionsError(f"kernel kind {kind!r}: expected one of {', '.join(KIND_MODULES)}")
    with _lock:
        for kind in kinds:
            _load_one(kind, compile_missing=True)
    return kinds


def describe() -> str:
    """One line: which path readings take in this process (for bench's output and logs)."""
    mode = kernel_mode()
    if mode is KernelMode.OFF:
        return f"OpenCV / numpy ({ENV}=off)"
    if not installed():
        return "OpenCV / numpy (robot-side install; the 'fast' extra adds the compiled kernels)"
    if _loaded:
        return f"compiled kernels (numba: {', '.join(_NAMES[k] for k in _loaded)})"
    if _missing:
        why = "; ".join(f"{_NAMES[k]}: {w}" for k, w in _missing.items())
        return f"OpenCV / numpy (compiled kernels not used: {why}; tactile-force kernels compiles them)"
    return "OpenCV / numpy (compiled kernels installed, not asked for yet)"
