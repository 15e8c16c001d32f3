"""numba's ``njit`` as the package's compiled per-frame kernels use it (edge/gate/kernels.py,
edge/depth/kernels.py; the ``fast`` extra; only they import this module, and edge/compiled_path.py
loads them off the reading path, so importing the package does not load numba): no fastmath (IEEE
operations in the order written, so a kernel can equal the OpenCV or numpy calls it replaces bit for
bit), no GIL held, no bounds checks, cached on disk in the user's cache folder (:func:`cache_dir`),
not in the install.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, Literal

import numba as nb

from .compiled_path import cache_dir

_log = logging.getLogger(__name__)
#: numba's settings (its attributes are set at run time: untyped)
_config: Any = nb.config


def compiled(what: str, inline: Literal["never", "always"] = "never") -> Callable[[Callable], Callable]:
    """Decorator: ``numba.njit`` with the kernels' options, cached on disk in :func:`cache_dir`
    (numba picks the folder when a kernel is decorated; where that one cannot be made, beside the
    module or numba's user cache as numba decides). Where no cache folder is writable (a read-only
    install without a home folder) numba refuses to cache: the kernel is then compiled in memory on
    every run (seconds at the first frame), and a warning naming ``what`` (e.g. 'contact gate
    kernels') says how to keep it."""

    def deco(fn: Callable) -> Callable:
        user_set = _config.CACHE_DIR
        _config.CACHE_DIR = cache_dir()  # read while the kernel is decorated, for this kernel only
        try:
            return nb.njit(cache=True, nogil=True, boundscheck=False, inline=inline)(fn)
        except RuntimeError as exc:  # numba: "cannot cache function ...: no locator available"
            _log.warning("%s: no writable cache folder (%s); they are compiled on every run. "
                         "Set NUMBA_CACHE_DIR to a writable folder to compile them once.", what, exc)
            return nb.njit(nogil=True, boundscheck=False, inline=inline)(fn)
        finally:
            _config.CACHE_DIR = user_set

    return deco
