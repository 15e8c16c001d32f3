"""The verdict against a latency budget, while the machine is watched (``tactile-force bench``).

The machine's load, CPU clock and the share of the cores other processes used are recorded
per attempt (:class:`~.machine.CpuWindow`). An attempt over budget on a busy machine is
repeated after a pause; when every attempt over budget was on a busy machine the verdict is
MACHINE_BUSY (no verdict on the model), apart from OVER_BUDGET, which only a quiet attempt
can give.
"""

from __future__ import annotations

import enum
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from .machine import CpuWindow, MachineState

BUDGET_MS = 1.0
JUDGED = "total"  # the stage the budget applies to: what a reading's total_ms shows
Window = Callable[[], "CpuWindow"]
K = TypeVar("K")


class BudgetVerdict(enum.Enum):
    """PASS, OVER_BUDGET (a quiet attempt over budget) or MACHINE_BUSY (no verdict)."""

    PASS = "PASS"
    OVER_BUDGET = "FAIL (over budget)"
    MACHINE_BUSY = "NO VERDICT (machine busy)"


@dataclass(frozen=True)
class Attempt:
    """One measurement: its total p99 (ms; None when nothing was measured) and the machine
    meanwhile."""

    total_p99_ms: float | None
    machine: MachineState


def judge(once: Callable[[], tuple[K, float]], budget_ms: float, repeats: int = 3, pause_s: float = 30.0,
          window: Window | None = None, sleep: Callable[[float], None] = time.sleep
          ) -> tuple[K, BudgetVerdict, list[Attempt]]:
    """Measure with ``once() -> (result, p99 ms)`` while watching the machine and judge the budget.

    A new attempt only after one over budget on a busy machine (``pause_s`` seconds later,
    ``repeats`` attempts at most); the attempt with the lowest p99 is kept. PASS when its p99
    <= ``budget_ms``; OVER_BUDGET when a quiet attempt was over it; MACHINE_BUSY when every
    attempt was over budget on a busy machine.

    Returns
    -------
    (kept result, verdict, attempts): the attempts carry each p99 (ms) and the machine state.
    """
    window = window or CpuWindow
    attempts: list[Attempt] = []
    kept: tuple[K, float] | None = None
    for k in range(max(1, repeats)):
        w = window()
        result, p99 = once()
        state = w.stop()
        attempts.append(Attempt(float(p99) if math.isfinite(p99) else None, state))
        if kept is None or p99 < kept[1]:
            kept = (result, p99)
        if p99 <= budget_ms or not state.busy:
            break
        if k + 1 < repeats:
            sleep(pause_s)
    assert kept is not None  # at least one attempt ran
    if kept[1] <= budget_ms:
        verdict = BudgetVerdict.PASS
    elif any(not a.machine.busy for a in attempts):
        verdict = BudgetVerdict.OVER_BUDGET
    else:
        verdict = BudgetVerdict.MACHINE_BUSY
    return kept[0], verdict, attempts

