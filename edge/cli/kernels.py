"""``tactile-force kernels``: compile the ``fast`` extra's kernels into numba's cache, once per environment.

    tactile-force kernels            # compile (or load) the gate's and depth stage's kernels; say where
    tactile-force kernels --check    # say whether they are compiled here; compile nothing (exit 1 if not)

A robot node never compiles (edge/compiled_path.py): it takes the kernels from the cache this verb
fills, and the equal OpenCV / numpy path where they are not there. A container image runs this verb
at build time so that every container starts with them.
"""

from __future__ import annotations

import argparse
import time

from .. import compiled_path


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of the kernels command."""
    parser.add_argument("--check", action="store_true",
                        help="only say whether the kernels are compiled for this environment (exit 1 if not)")


def main(args: argparse.Namespace) -> int:
    """Compile or check; 0 when the kernels are ready, 1 when ``--check`` finds them missing."""
    from ..errors import MissingExtraError

    if not compiled_path.installed():
        raise MissingExtraError("numba", "fast", "tactile-force kernels (the compiled kernels)")
    where = compiled_path.cache_dir()
    if args.check:
        from ..report.logs import quiet_loggers

        compiled_path.set_kernel_mode(compiled_path.KernelMode.AUTO)
        with quiet_loggers(compiled_path.__name__):  # this verb says it itself, once
            for kind in compiled_path.KIND_MODULES:
                compiled_path.request(kind)
        missing = [k for k in compiled_path.KIND_MODULES if k not in compiled_path.loaded_kinds()]
        if missing:
            print(f"kernels: not compiled for this environment ({', '.join(missing)}; cache {where}); "
                  "run: tactile-force kernels")
            return 1
        print(f"kernels: compiled and cached in {where}; readings take them")
        return 0
    t0 = time.perf_counter()
    kinds = compiled_path.load()
    print(f"kernels: {', '.join(kinds)} ready in {time.perf_counter() - t0:.1f} s, cached in {where} "
          "(a container image keeps this folder to start with them)")
    return 0
