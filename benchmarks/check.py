"""The under-1 ms check: the best RGBmod bundle's end-to-end p99 (gate + inference, one
thread, int8, frames in contact) must be within the budget on this machine."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from .bundles import ModelConfig, rgbmod_candidates, trained_int8
from .latency import COMPACT, LatencyCase, LatencyResult, measure

BUDGET_MS = 1.0
Measure = Callable[[LatencyCase], LatencyResult]


@dataclass
class CheckResult:
    """passed: best.gate+inference p99 <= budget_ms. others: D / RGBmod+D figures beside it;
    torch: the paper-style PyTorch eager fp32 full-resolution RGBmod run."""

    passed: bool
    budget_ms: float
    best: LatencyResult
    which: str
    others: dict[str, LatencyResult]
    torch: LatencyResult | None
    candidates: list[tuple[str, float, LatencyResult]] = ()  # (which, synthetic RE, timing), most accurate first

    @property
    def p99_ms(self) -> float:
        return self.best.stages["gate+inference"].p99

    @property
    def speedup_p50(self) -> float:
        """torch eager inference p50 / our gate+inference p50."""
        if self.torch is None:
            return float("nan")
        return self.torch.stages["inference"].p50 / self.best.stages["gate+inference"].p50

    def report(self) -> str:
        s = self.best.stages
        lines = []
        if len(self.candidates) > 1:
            lines.append(f"trained int8 RGBmod candidates (most accurate first; the most accurate whose p99 fits "
                         f"{self.budget_ms:g} ms is kept):")
            for which, re, r in self.candidates:
                gi = r.stages["gate+inference"]
                fits = "fits" if gi.p99 <= self.budget_ms else "over budget"
                lines.append(f"  {which:<34} RE {re:.3f}  gate+inference p50 {gi.p50:.3f} p99 {gi.p99:.3f} ms  {fits}")
        lines += [f"best RGBmod: {self.which}",
                 f"  {'stage':<16} {'p50 ms':>8} {'p90 ms':>8} {'p99 ms':>8}   ({s['gate'].n} frames in contact, 1 thread)"]
        for k in ("gate", "inference", "gate+inference", "total"):
            p = s[k]
            lines.append(f"  {k:<16} {p.p50:8.3f} {p.p90:8.3f} {p.p99:8.3f}")
        for name, r in self.others.items():
            o = r.stages
            lines.append(f"{name}: gate {o['gate'].p50:.3f} / depth {o['depth'].p50:.3f} / inference "
                         f"{o['inference'].p50:.3f} ms p50; total p50 {o['total'].p50:.3f} p99 {o['total'].p99:.3f} ms")
        if self.torch is not None:
            t = self.torch.stages["inference"]
            lines.append(f"paper-style PyTorch eager fp32, full-res RGBmod, 1 thread: inference p50 {t.p50:.2f} p99 "
                         f"{t.p99:.2f} ms ({t.n} frames) -> ours is {self.speedup_p50:.0f}x faster at p50 "
                         f"(paper: 0.9 ms on an RTX 3060 GPU)")
        verdict = "PASS" if self.passed else "FAIL"
        lines.append(f"{verdict}: gate + inference p99 {self.p99_ms:.3f} ms {'<=' if self.passed else '>'} "
                     f"budget {self.budget_ms:.3f} ms")
        return "\n".join(lines)


def run_check(measure_fn: Measure | None = None, frames: int = 1000, budget_ms: float = BUDGET_MS,
              torch_frames: int = 30, with_torch: bool = True) -> CheckResult:
    """Measure the best RGBmod (and D, RGBmod+D, torch eager beside it) and judge the budget.
    measure_fn: how a case is timed (default :func:`benchmarks.latency.measure`; tests inject fakes)."""
    measure_fn = measure_fn or measure
    measured = []
    for path, which, re in rgbmod_candidates():
        r = measure_fn(LatencyCase(COMPACT, "int8-static", threads=1, frames=frames, warmup=100, bundle=path))
        measured.append((which, re, r))
    fitting = [m for m in measured if m[2].stages["gate+inference"].p99 <= budget_ms]
    which, re, best = fitting[0] if fitting else min(measured, key=lambda m: m[2].stages["gate+inference"].p99)
    if len(measured) > 1 and measured[0][0] != which:
        which += f" (accuracy cost vs the most accurate, {measured[0][0]}: RE {measured[0][1]:.3f} -> {re:.3f})"
    others = {}
    for v in ("d", "rgbmod+d"):
        cfg = ModelConfig(v, COMPACT.width, COMPACT.k)
        path = trained_int8(v, cfg)
        label = f"{cfg.label} int8" + (" (trained)" if path else " (random weights)")
        others[label] = measure_fn(LatencyCase(cfg, "int8-static", threads=1, frames=max(50, frames // 5),
                                               bundle=path))
    torch_res = None
    if with_torch:
        torch_res = measure_fn(LatencyCase(ModelConfig("rgbmod", 1.0, 1), "fp32", engine="torch-eager", threads=1,
                                           frames=torch_frames, warmup=3))
    p99 = best.stages["gate+inference"].p99
    return CheckResult(bool(p99 <= budget_ms), budget_ms, best, which, others, torch_res, measured)
