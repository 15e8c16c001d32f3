"""numba's ``njit`` as the package's compiled per-frame kernels use it (edge/gate/kernels.py,
edge/depth/kernels.py; only they import this module, so importing the package does not load
numba): no fastmath (IEEE operations in the order written, so a kernel can equal the OpenCV or
numpy calls it replaces bit for bit), no GIL held, no bounds checks, cached on disk.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Literal

import numba as nb

_log = logging.getLogger(__name__)


def compiled(what: str, inline: Literal["never", "always"] = "never") -> Callable[[Callable], Callable]:
    """Decorator: ``numba.njit`` with the kernels' options, cached on disk (next to the module,
    else in the user's cache folder or ``NUMBA_CACHE_DIR``). Where no cache folder is writable (a
    read-only install without a home folder) numba refuses to cache: the kernel is then compiled
    in memory on every run (seconds at the first frame), and a warning naming ``what`` (e.g.
    'contact gate kernels') says how to keep it."""

    def deco(fn: Callable) -> Callable:
        try:
            return nb.njit(cache=True, nogil=True, boundscheck=False, inline=inline)(fn)
        except RuntimeError as exc:  # numba: "cannot cache function ...: no locator available"
            _log.warning("%s: no writable cache folder (%s); they are compiled on every run. "
                         "Set NUMBA_CACHE_DIR to a writable folder to compile them once.", what, exc)
            return nb.njit(nogil=True, boundscheck=False, inline=inline)(fn)

    return deco
