"""argparse types shared by every subcommand: a bad value becomes argparse's usage error
(exit 2) naming the flag, before any work starts.

Every numeric flag is bounded at both ends (tiny and huge values included) by :func:`within`
with a bound of :mod:`tactile_force.edge.limits` (the same bounds the options records and
constructors check) or a flag's own :class:`~tactile_force.edge.typed_json.Check`; the
parser's type keeps it as ``check`` so tests can list every flag's range.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any

from ..typed_json import Check, describe_type


def within(kind: type[int] | type[float], chk: Check) -> Callable[[str], Any]:
    """argparse type: an integer (``kind=int``) or a finite number (``kind=float``) within the
    bounds of ``chk``."""
    want = describe_type(kind, chk, None)

    def parse(text: str) -> int | float:
        try:
            v: int | float = int(text) if kind is int else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {'an integer' if kind is int else 'a number'}") from None
        if isinstance(v, float) and not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{text}: expected a finite {want.removeprefix('a ')}")
        if not chk.in_range(v):
            raise argparse.ArgumentTypeError(f"{text}: expected {want}")
        return v

    parse.check = chk  # type: ignore[attr-defined]
    return parse


def int_at_least(minimum: int, maximum: int = 2**31 - 1) -> Callable[[str], Any]:
    """argparse type: an integer in ``minimum..maximum``."""
    return within(int, Check(ge=minimum, le=maximum))


def float_in(low: float, high: float, *, low_open: bool = False, high_open: bool = False) -> Callable[[str], Any]:
    """argparse type: a finite number in the range ``low..high`` (open at an end when asked)."""
    return within(float, Check(gt=low if low_open else None, ge=None if low_open else low,
                               lt=high if high_open else None, le=None if high_open else high))


#: argparse types of earlier versions, bounded only below (the CLI's flags use :func:`within`).
positive_int = int_at_least(1, 2**63 - 1)
non_negative_int = int_at_least(0, 2**63 - 1)
positive_float = within(float, Check(gt=0, le=1.7976931348623157e308))
finite_float = within(float, Check(ge=-1.7976931348623157e308, le=1.7976931348623157e308))
