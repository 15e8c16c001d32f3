"""argparse types shared by every subcommand: a bad value becomes argparse's usage error (exit 2)."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def int_at_least(minimum: int) -> Callable[[str], int]:
    """argparse type: an integer >= ``minimum``."""

    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if v < minimum:
            raise argparse.ArgumentTypeError(f"{v}: expected an integer >= {minimum}")
        return v

    return parse


#: argparse type: an integer >= 1.
positive_int = int_at_least(1)
#: argparse type: an integer >= 0.
non_negative_int = int_at_least(0)


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"{v}: expected a finite number > 0")
    return v


def finite_float(text: str) -> float:
    """argparse type: a finite number (no nan, inf)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{v}: expected a finite number")
    return v


def float_in(low: float, high: float, *, low_open: bool = False, high_open: bool = False) -> Callable[[str], float]:
    """argparse type: a finite number in the range ``low..high`` (``(`` / ``)`` when open)."""

    def parse(text: str) -> float:
        v = finite_float(text)
        if (v < low or (low_open and v == low)) or (v > high or (high_open and v == high)):
            lo, hi = "(" if low_open else "[", ")" if high_open else "]"
            raise argparse.ArgumentTypeError(f"{v:g}: expected a number in {lo}{low:g}, {high:g}{hi}")
        return v

    return parse
