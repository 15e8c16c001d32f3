"""Callgrind's client requests from Python, so one run under valgrind counts each stage apart.

Valgrind recognises a request by a special instruction sequence the program executes (a no-op
when it runs natively); callgrind's requests start and stop its instrumentation, turn counting
on and off and write the counts so far to a file named for the stage (``DUMP_STATS_AT``). The
sequence is emitted here through numba (an LLVM inline-assembly call), for x86-64 only
(:data:`SUPPORTED`): the instructions benchmark counts every stage of a bundle in one run; on
another architecture it says so and counts nothing (benchmarks/instructions.py).

Run the program with ``--instr-atstart=no --collect-atstart=no``: its imports and set-up then run
uninstrumented (several times faster) and count nothing; :class:`Segment` counts what runs
inside it.
"""

from __future__ import annotations

import platform
from collections.abc import Callable
from types import TracebackType

import numpy as np

#: Whether this host's architecture has the request sequence here (x86-64).
SUPPORTED = platform.machine().lower() in ("x86_64", "amd64")

_CT = (ord("C") << 24) | (ord("T") << 16)  # callgrind's base: VG_USERREQ_TOOL_BASE('C', 'T')
DUMP_STATS_AT = _CT + 3
ZERO_STATS = _CT + 1
TOGGLE_COLLECT = _CT + 2
START_INSTRUMENTATION = _CT + 4
STOP_INSTRUMENTATION = _CT + 5
RUNNING_ON_VALGRIND = 0x1001

_request: Callable[[int, int], int] | None = None


def _compile() -> Callable[[int, int], int]:
    """``request(code, arg) -> int``: valgrind's answer, 0 when not under valgrind (compiled once)."""
    import llvmlite.binding as llvm
    from llvmlite import ir
    from numba import njit, types
    from numba.extending import intrinsic

    llvm.initialize_native_asmparser()  # numba does not: inline assembly needs it

    @intrinsic
    def _raw(typingctx, code, arg):
        sig = types.uint64(types.uint64, types.uint64)

        def codegen(context, builder, signature, args):
            i64, i32 = ir.IntType(64), ir.IntType(32)
            block = builder.alloca(ir.ArrayType(i64, 6))  # the request and its five arguments
            values = [args[0], args[1]] + [ir.Constant(i64, 0)] * 4
            for k, v in enumerate(values):
                builder.store(v, builder.gep(block, [ir.Constant(i32, 0), ir.Constant(i32, k)]))
            # rdx = the request at rax's block (rdx in: the answer outside valgrind), valgrind.h's amd64 form
            asm = ir.InlineAsm(ir.FunctionType(i64, [i64, i64]),
                               "rolq $$3, %rdi ; rolq $$13, %rdi\n\trolq $$61, %rdi ; rolq $$51, %rdi\n\t"
                               "xchgq %rbx, %rbx", "={dx},{ax},0,~{cc},~{memory},~{rdi}", side_effect=True)
            return builder.call(asm, [builder.ptrtoint(block, i64), ir.Constant(i64, 0)])

        return sig, codegen

    @njit(cache=False)
    def request(code: int, arg: int) -> int:  # pragma: no cover - compiled
        return _raw(np.uint64(code), np.uint64(arg))  # type: ignore[call-arg]  # typingctx is numba's

    return request


def request(code: int, arg: int = 0) -> int:
    """Send one client request (``code``, one argument); valgrind's answer, 0 natively."""
    global _request
    if not SUPPORTED:
        raise RuntimeError(f"valgrind client requests are made here on x86-64 only, not {platform.machine()}")
    if _request is None:
        _request = _compile()
    return int(_request(code, arg))


def on_valgrind() -> bool:
    """Whether this process runs under valgrind."""
    return SUPPORTED and request(RUNNING_ON_VALGRIND) > 0


class Segment:
    """``with Segment("bare"): ...`` counts what runs inside alone and writes it to a dump whose
    trigger names it (``Client Request: bare``); nothing outside is counted."""

    def __init__(self, name: str) -> None:
        if not name.isidentifier():
            raise ValueError(f"a segment's name must be an identifier, not {name!r}")
        self._name = np.frombuffer(name.encode() + b"\0", np.uint8).copy()  # kept alive: valgrind reads it

    def __enter__(self) -> Segment:
        request(ZERO_STATS)
        request(START_INSTRUMENTATION)
        request(TOGGLE_COLLECT)
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        request(TOGGLE_COLLECT)
        request(DUMP_STATS_AT, int(self._name.ctypes.data))
        request(STOP_INSTRUMENTATION)
