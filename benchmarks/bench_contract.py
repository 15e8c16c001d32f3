"""The ``tactile-force bench`` report's contract: ``report.json``'s typed records (docs/bench.md)
and the verdict over bundles; :mod:`benchmarks.bench` measures, :mod:`benchmarks.bench_report` renders."""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from tactile_force.edge.typed_json import check

from .harness.budget import Attempt
from .harness.machine import Machine

SCHEMA = "tactile-force-bench/1"
REPORT_JSON, REPORT_MD, PLOT_PNG = "report.json", "report.md", "pareto.png"
#: The stages a reading's latency carries, in report order (``depth`` only for depth variants).
STAGES = ("source", "gate", "depth", "inference", "glue", "total")
#: Readings not counted before each measurement (back to back and at the cadence).
WARMUP = 30


# ----------------------------------------------------------------------------- the contract
@dataclass
class Timing:
    """Percentiles of one stage in ms over ``n`` frames (None: not measured, e.g. depth of RGBmod)."""

    p50: float | None
    p90: float | None
    p99: float | None
    mean: float | None
    n: int


@dataclass
class Cadence:
    """A bundle measured with frames arriving at ``fps`` per second (each frame due at
    t0 + i / fps, the source sleeping until it is): ``total_ms`` as :attr:`BundleResult.total_ms`
    (frame arrival -> reading, over the frames read), ``cpu_share`` the process CPU time over
    the wall time meanwhile (0.05 = 5 % of one core; None: not measured), ``missed`` frames the
    runtime was late for (skipped, as a camera's newest-frame grabber skips them; no reading
    measured for them), ``bare_ms`` the bundle's graph alone in a bare onnxruntime session,
    one call per 1/fps tick (:func:`benchmarks.harness.latency.bare_at_cadence`): the floor no
    runtime around this network can beat at this cadence on this host (None: not measured)."""

    fps: float = field(metadata=check(gt=0))
    total_ms: Timing
    cpu_share: float | None
    missed: int = 0
    bare_ms: Timing | None = None


@dataclass
class BinError:
    """RE (dimensionless) and MAE (N), mean and std (ddof=0), over ``n`` CNN readings."""

    n: int
    re_mean: float | None
    re_std: float | None
    mae_mean: float
    mae_std: float


@dataclass
class BenchError:
    """Error vs truth of a bundle on labelled data, measured through the runtime: overall
    figures over the ``n`` readings where the CNN gave a force and truth > 0 N, per 1 N bin
    of the true force (``"3-4"``: 3 <= f < 4 N), the labelled data and background used,
    the frames with truth and how many with truth >= 1 N got no force (``missed``)."""

    n: int
    re_mean: float | None
    re_std: float | None
    mae_mean: float
    mae_std: float
    per_bin: dict[str, BinError]
    data: str
    background: str | None
    frames_with_truth: int
    missed: int


@dataclass
class BundleResult:
    """One bundle's row: where it is, what it is, its latency through ``ForceRuntime`` back to
    back (``total_ms``: frame arrival -> reading, what a reading's total_ms shows; ``stages_ms``:
    source, gate, depth, inference, glue) and at the sensor's cadence (``cadence``; None when
    not measured, e.g. by ``study`` or in a report from before it was measured), its error on
    labelled data (None without ``--data``), the error its manifest records (``manifest_re``,
    on the data it was made with), and its verdict against the budget, judged on the total
    p99 at the cadence (back to back without one): PASS, OVER_BUDGET, MACHINE_BUSY,
    TOO_FEW_READINGS, or NO_READINGS (most bench frames gave no force, e.g. the bundle fails on
    them: ``note`` says why). ``attempts`` carry the judged p99.
    ``precision`` is what the graph holds, as ``bundle verify`` reads it
    (:func:`tactile_force.edge.bundle.graph_facts.graph_precision`), not the manifest's word; ``note``
    says when the manifest claims another."""

    path: str
    name: str
    variant: str
    precision: str
    total_ms: Timing
    stages_ms: dict[str, Timing]
    error: BenchError | None
    manifest_re: float | None
    verdict: str
    attempts: list[Attempt] = field(default_factory=list)
    note: str = ""
    cadence: Cadence | None = None

    @property
    def judged_ms(self) -> Timing:
        """The total the verdict is judged on: at the cadence when measured, else back to back."""
        return self.cadence.total_ms if self.cadence is not None else self.total_ms


@dataclass
class BenchReport:
    """What ``tactile-force bench`` measured (``report.json``; docs/bench.md).

    verdict: PASS when every bundle's judged total p99 (at the cadence when measured) is
    within ``budget_ms``; else as :func:`overall_verdict`. ``frames``: readings measured back
    to back per bundle (at the cadence: each bundle's ``cadence.total_ms.n`` and its
    ``missed``)."""

    schema: str
    machine: Machine
    budget_ms: float
    threads: int
    frames: int
    verdict: str
    bundles: list[BundleResult]
    command: str = ""
    #: the per-frame image work's path on this host: the ``fast`` extra's compiled kernels or the OpenCV /
    #: numpy calls of the robot-side install (edge/compiled_path.py; the readings are the same)
    image_path: str = ""

    def to_json(self) -> dict:
        """Plain JSON values (NaN written as null)."""
        from tactile_force.edge.typed_json import to_json

        return to_json(self)

    @classmethod
    def from_json(cls, raw: object) -> BenchReport:
        """Parse and validate a ``report.json`` value; a wrong field raises
        :class:`tactile_force.edge.typed_json.TypedJsonError` naming its path."""
        from tactile_force.edge.typed_json import from_json

        return from_json(cls, raw, "report.json")

    @property
    def passed(self) -> bool:
        return self.verdict == "PASS"


def _f(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def _timing(p) -> Timing:
    return Timing(_f(p.p50), _f(p.p90), _f(p.p99), _f(p.mean), int(p.n))


def overall_verdict(verdicts: Sequence[str]) -> str:
    """PASS when all pass; else OVER_BUDGET when any is over budget; else NO_READINGS when a
    bundle gave no force on the bench frames; else TOO_FEW_READINGS when a bundle's p99 rests
    on too few readings; else MACHINE_BUSY."""
    if verdicts and all(v == "PASS" for v in verdicts):
        return "PASS"
    for v in ("OVER_BUDGET", "NO_READINGS", "TOO_FEW_READINGS"):
        if v in verdicts:
            return v
    return "MACHINE_BUSY"



def read_report(path: str | os.PathLike) -> BenchReport:
    """Read a report.json back into a :class:`BenchReport`."""
    return BenchReport.from_json(json.loads(Path(path).read_text()))
