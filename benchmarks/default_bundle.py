"""Which shipped bundle ships as the default (default_bundle.md): ``tactile-force bench`` run several
times on one host, each RGB bundle's p99 at the sensor's cadence against its error, and the bundles on
the Pareto front of (RE, p99) in each run.

    python -m benchmarks default-bundle --bench-runs 5 --out docs/benchmarks   # runs bench 5 times
    python -m benchmarks default-bundle --reports R1/report.json ... --out DIR  # judges earlier runs

The default is the bundle on the front in the most runs (ties: the lower median p99); only bundles that
read from the RGB image alone compete (a depth bundle needs a depth calibration of the user's sensor
before it reads anything). The error is each bundle's manifest RE on the synthetic test split, the
latency the end-to-end total p99 at 60 fps through ``ForceRuntime`` (what a controller meets).
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import subprocess
import sys
import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

from .bench_contract import BenchReport, read_report
from .harness.stats import markdown_table

#: the variants that compete for the default: those reading the RGB image alone
RGB_VARIANTS = ("rgbmod",)


@dataclass
class Point:
    """One bundle in one bench run: its name, its folder when measured, variant, manifest RE, and
    totals at the cadence and back to back (ms)."""

    name: str
    folder: str
    variant: str
    re: float
    p50: float
    p99: float
    bare_p99: float | None
    b2b_p50: float
    b2b_p99: float
    verdict: str


def points(report: BenchReport) -> list[Point]:
    """The bundles of one run that have a manifest RE and a cadence measurement."""
    out = []
    for b in report.bundles:
        c = b.cadence
        if c is None or b.manifest_re is None or c.total_ms.p99 is None or c.total_ms.p50 is None:
            continue
        out.append(Point(b.name, Path(b.path).name, b.variant, float(b.manifest_re), c.total_ms.p50, c.total_ms.p99,
                         c.bare_ms.p99 if c.bare_ms is not None else None, _ms(b.total_ms.p50), _ms(b.total_ms.p99),
                         b.verdict))
    return out


def _ms(v: float | None) -> float:
    return float("nan") if v is None else float(v)


def front(run: list[Point], everyone: bool = False) -> set[str]:
    """The names on the Pareto front of (RE, p99) among one run's RGB bundles (``everyone``: all of
    them): none other is at least as good in both and better in one."""
    rgb = [p for p in run if everyone or p.variant in RGB_VARIANTS]
    return {p.name for p in rgb
            if not any(q.re <= p.re and q.p99 <= p.p99 and (q.re < p.re or q.p99 < p.p99) for q in rgb if q is not p)}


def choose(runs: list[list[Point]]) -> str:
    """The bundle on the front in the most runs; ties broken by the lower median p99."""
    fronts = [front(r) for r in runs]
    names = sorted({p.name for r in runs for p in r if p.variant in RGB_VARIANTS})
    if not names:
        raise ValueError("no RGB bundle with a manifest RE and a cadence measurement in the reports")

    def key(n: str) -> tuple[int, float]:
        return (-sum(n in f for f in fronts), statistics.median(p.p99 for r in runs for p in r if p.name == n))
    return min(names, key=key)


def _span(values: list[float]) -> str:
    return f"{statistics.median(values):.2f} ({min(values):.2f}-{max(values):.2f})"


def page(runs: list[list[Point]], reports: list[BenchReport], command: str, measured_at: str) -> str:
    from .harness.machine import header

    fronts = [front(r) for r in runs]
    chosen = choose(runs)
    names = list(dict.fromkeys(p.name for r in runs for p in r))
    rows = []
    for n in names:
        ps = [p for r in runs for p in r if p.name == n]
        bare = [p.bare_p99 for p in ps if p.bare_p99 is not None]
        b2b = f"{_span([p.b2b_p50 for p in ps])} / {_span([p.b2b_p99 for p in ps])}"
        rows.append([n, ps[0].folder, ps[0].variant, f"{ps[0].re:.3f}", _span([p.p50 for p in ps]),
                     _span([p.p99 for p in ps]), _span(bare) if bare else "-", b2b,
                     f"{sum(p.verdict == 'PASS' for p in ps)} of {len(ps)}",
                     f"{sum(n in f for f in fronts)} of {len(runs)}" if ps[0].variant in RGB_VARIANTS else "-"])
    how = "; ".join(dict.fromkeys(f"`{r.command}`" for r in reports if r.command)) or "`tactile-force bench`"
    notes = (f"{len(runs)} runs of `tactile-force bench` (60 fps, budget p99 <= 1 ms, one thread) on one host, "
             f"measured at {measured_at} ({how}; `--bench-runs N` runs them itself); per cell the median "
             "(min-max) over runs. RE: each bundle's manifest RE on "
             "the synthetic test split (the same 424 frames for the RGBmod bundles). Front: the runs in which the "
             "bundle was on the Pareto front of (RE, total p99 at 60 fps) among the RGB bundles (a depth bundle "
             "needs a depth calibration of the user's sensor before it reads; it does not compete).")
    m = reports[0].machine
    lines = [header("Which bundle ships as the default", command, m, notes), "",
             markdown_table(["bundle", "folder then", "variant", "RE", "60 fps total p50 ms", "60 fps total p99 ms",
                             "its graph alone p99 ms", "back to back p50 / p99 ms", "PASS", "on the front"], rows), "",
             f"**Chosen: {chosen}**, on the front in {sum(chosen in f for f in fronts)} of {len(runs)} runs "
             f"(among every bundle, depth ones included: {sum(chosen in front(r, True) for r in runs)} of "
             f"{len(runs)}). It ships as edge/models/default.", ""]
    return "\n".join(lines) + "\n"


def _bench_runs(n: int, tmp: Path) -> list[Path]:
    from tqdm import tqdm

    out = []
    for k in tqdm(range(n), desc="bench runs", unit="run"):
        d = tmp / f"run{k + 1}"
        p = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "bench", "--out", str(d), "--repeats", "1"],
                           capture_output=True, text=True)
        if p.returncode not in (0, 1) or not (d / "report.json").is_file():
            raise RuntimeError(f"tactile-force bench exited {p.returncode}: {p.stderr.strip()[-400:]}")
        out.append(d / "report.json")
    return out


def _measured_at(report_json: Path) -> str:
    md = report_json.with_name("report.md")
    m = re.search(r"^Commit: (\S+)", md.read_text(), re.M) if md.is_file() else None
    return f"commit {m.group(1)}" if m else "the commit named in each report"


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """``python -m benchmarks default-bundle``: bench runs (or ``--reports``) -> default_bundle.md + .json."""
    from .harness.machine import command_line
    from .harness.paths import source_commit, write_record_and_page

    with tempfile.TemporaryDirectory(prefix="default-bundle-") as d:
        paths = list(args.reports) if args.reports else _bench_runs(args.bench_runs, Path(d))
        reports = [read_report(p) for p in paths]
        runs = [points(r) for r in reports]
        at = _measured_at(paths[0]) if args.reports else f"commit {source_commit()}"
    text = page(runs, reports, command_line(argv), at)
    record = {"measured_at": at, "chosen": choose(runs), "runs": [[asdict(p) for p in r] for r in runs]}
    written = write_record_and_page(args.out, "default_bundle", json.dumps(record, indent=1) + "\n", text)
    print(text)
    print(f"wrote {written}")
    return 0
