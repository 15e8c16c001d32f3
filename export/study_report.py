"""What ``tactile-force study`` writes: the study.json contract (:class:`StudyReport` and its
records), the configurations table, study.md and the Pareto plot."""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

SCHEMA = "tactile-force-study/1"
STUDY_JSON, STUDY_MD, PLOT_PNG = "study.json", "study.md", "pareto.png"


@dataclass
class Settings:
    """How a configuration was made: mode (fp32 / fp16 / int8-dynamic / int8-static), the
    calibration method and per-channel weights (int8 static), nodes kept float beyond the
    head (``keep_float``)."""

    mode: str
    method: str | None = None
    per_channel: bool | None = None
    keep_float: list[str] = field(default_factory=list)


@dataclass
class ConfigError:
    """Error of a configuration on the labelled data, through the runtime: vs truth (RE, MAE
    over the ``n`` readings where the CNN gave a force and truth > 0 N, as ``run`` reports)
    and vs the fp32 bundle on the same frames (``vs_fp32_mae``: mean |f - f_fp32| in N,
    ``vs_fp32_max``: max, over ``n_vs_fp32`` frames both gave a force for)."""

    n: int
    re_mean: float | None
    re_std: float | None
    mae_mean: float
    mae_std: float
    vs_fp32_mae: float | None
    vs_fp32_max: float | None
    n_vs_fp32: int


@dataclass
class Latency:
    """Total latency through ForceRuntime on this host in ms (frame arrival -> reading)."""

    p50: float | None
    p99: float | None
    inference_p50: float | None
    n: int


@dataclass
class Configuration:
    """One configuration: its name, settings, error (None: no CNN reading), latency, whether
    it is on the Pareto front (error vs p99), within the budget, and the bundle kept for it
    (front only; None otherwise)."""

    name: str
    settings: Settings
    error: ConfigError | None
    latency_ms: Latency
    pareto: bool = False
    within_budget: bool = False
    bundle: str | None = None
    note: str = ""


@dataclass
class Sensitivity:
    """One node kept float on top of the base int8 static configuration: the mean |f - f_fp32|
    (N) on the labelled frames with it, and the share of the base's |f - f_fp32| it buys back."""

    node: str
    op: str
    vs_fp32_mae: float
    bought_back: float


@dataclass
class StudyReport:
    """What ``tactile-force study`` measured (study.json).

    configurations: fp32 first; recommended: the name of the most accurate configuration
    (lowest RE vs truth) whose p99 is within ``budget_ms``, None when none is (``note`` says
    why when that is not the latency itself, e.g. too few readings for a p99)."""

    schema: str
    source: str
    variant: str
    data: str
    calibration: str
    same_frames: bool
    budget_ms: float
    threads: int
    frames: int
    machine: dict[str, str | int | float | None]
    configurations: list[Configuration]
    sensitivity: list[Sensitivity]
    sensitivity_base: str | None
    recommended: str | None
    seconds: float
    command: str = ""
    note: str = ""

    def to_json(self) -> dict:
        from tactile_force.edge.typed_json import to_json

        return to_json(self)

    @classmethod
    def from_json(cls, raw: object) -> StudyReport:
        from tactile_force.edge.typed_json import from_json

        return from_json(cls, raw, "study.json")


def _num(v: float | None, d: int = 3) -> str:
    return "-" if v is None else f"{v:.{d}f}"


def _row_text(c: Configuration) -> str:
    e = c.error
    return (f"RE {_num(e.re_mean if e else None)}, vs fp32 {_num(e.vs_fp32_mae if e else None)} N, "
            f"p99 {_num(c.latency_ms.p99)} ms")


def table(report: StudyReport) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the configurations table."""
    head = ["#", "configuration", "RE", "MAE (N)", "mean abs(f - fp32) (N)", "max abs(f - fp32) (N)",
            "inference p50 ms", "total p50 ms", "total p99 ms", "Pareto", "within budget"]
    rows = []
    for i, c in enumerate(report.configurations, 1):
        e = c.error
        name = c.name + (" **(recommended)**" if c.name == report.recommended else "")
        rows.append([str(i), name, _num(e.re_mean if e else None, 4), _num(e.mae_mean if e else None),
                     _num(e.vs_fp32_mae if e else None, 4), _num(e.vs_fp32_max if e else None, 4),
                     _num(c.latency_ms.inference_p50), _num(c.latency_ms.p50), _num(c.latency_ms.p99),
                     "yes" if c.pareto else "", "yes" if c.within_budget else "no"])
    return head, rows


def _rel(path: str | None) -> str:
    """``path`` relative to the working directory when inside it (pages stay machine-neutral)."""
    if not path:
        return ""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return path


def markdown(report: StudyReport, title: str = "Quantization study") -> str:
    """study.md: command, machine, the table, the sensitivity ranking, the recommendation."""
    head, rows = table(report)
    m = report.machine
    e0 = report.configurations[0].error
    lines = [f"# {title}", "", f"Command: `{report.command}`" if report.command else "", "",
             f"Machine: {m.get('cpu')}, {m.get('cores')} logical cores, {m.get('os')}, Python {m.get('python')}; "
             f"{m.get('versions')}. At start: {m.get('background_load')}.", "",
             f"Source: `{_rel(report.source)}` ({report.variant}, fp32). Error: `{_rel(report.data)}` replayed through "
             f"ForceRuntime as `tactile-force run` does ({e0.n if e0 else 0} CNN readings with truth). Calibration: "
             f"{report.calibration}" + (" - **the same frames as the error** (optimistic for int8 static; give "
                                        "--calib)" if report.same_frames else "") + ".",
             f"Latency: ForceRuntime, virtual DIGIT frames in contact from memory, {report.threads} thread(s), "
             f"{report.frames} readings per configuration; budget p99 <= {report.budget_ms:g} ms. "
             f"Took {report.seconds:.0f} s.", "",
             "| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    lines += ["", "Recommended (most accurate within the budget): "
              + (f"**{report.recommended}**" if report.recommended else
                 f"none - {report.note}" if report.note else
                 f"none - no configuration's p99 fits {report.budget_ms:g} ms on this host")]
    kept = [c for c in report.configurations if c.bundle]
    if kept:
        lines += ["", "Bundles kept (Pareto front and the recommendation): "
                  + ", ".join(f"`{_rel(c.bundle)}`" for c in kept)]
    if report.sensitivity:
        lines += ["", f"## Per-node sensitivity (one node kept float on top of {report.sensitivity_base})", "",
                  "| node | op | mean abs(f - fp32) (N) | share of the base's error bought back |",
                  "|---|---|---|---|"]
        lines += [f"| {s.node} | {s.op} | {s.vs_fp32_mae:.4f} | {100 * s.bought_back:+.0f} % |"
                  for s in report.sensitivity]
    return "\n".join(lines).replace("\n\n\n", "\n\n") + "\n"


def write_study(report: StudyReport, out: Path) -> list[Path]:
    """Write study.json, study.md and pareto.png into ``out``."""
    from tactile_force.benchmarks.bench import write_json
    from tactile_force.edge.report.plots import ParetoPoint, error_vs_latency

    out.mkdir(parents=True, exist_ok=True)
    js = write_json(out / STUDY_JSON, report.to_json())
    (out / STUDY_MD).write_text(markdown(report))
    pts = [ParetoPoint(c.name, c.latency_ms.p99 if c.latency_ms.p99 is not None else math.nan,
                       c.error.re_mean if c.error is not None else None) for c in report.configurations]
    plot = error_vs_latency(pts, report.budget_ms, out / PLOT_PNG, numbered=True,
                            title=f"{report.variant} study (points numbered as the table's # column)")
    return [js, out / STUDY_MD, plot]


def read_study(path: str | os.PathLike) -> StudyReport:
    """Read a study.json back into a :class:`StudyReport`."""
    return StudyReport.from_json(json.loads(Path(path).read_text()))
