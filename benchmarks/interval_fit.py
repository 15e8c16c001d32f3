"""Fit (or refresh) the ``interval`` of a bundle on virtual DIGIT grasps it never saw.

    python -m benchmarks.interval_fit                      # every bundle shipped in the package
    python -m benchmarks.interval_fit path/to/bundle --grasps 60 --coverage 0.9

The bundle's model (with its force calibration, if any) runs through :class:`ForceRuntime`
on fresh virtual DIGIT grasps: seed :data:`CAL_SEED` (used nowhere else: not in training,
not in choosing the model, not in the report, which uses :data:`REPORT_SEED`), indenters
of the S1 *test* split (the reference models never trained or chose on them). Each
reading in contact gives one (estimate, true force) pair, each ``no_contact`` reading one
gate-closed true force; :func:`tactile_force.edge.bundle.interval.fit_interval` makes the table.
Neither the model nor its ONNX file changes: only ``model.json`` is rewritten, through the
typed Manifest and ``write_bundle``. If the ONNX file changes while the grasps run (another
tool rewrote the bundle), the fit is repeated on the new model.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Fresh virtual DIGIT seeds (VirtualDigitSource), used nowhere else in the project.
CAL_SEED = 2101  #: calibration grasps: the interval of the shipped bundles is fitted on these
REPORT_SEED = 2102  #: report grasps: docs/benchmarks/intervals.md only, never fitted on
#: Peak forces of the grasps (N): the whole range, with some saturated (>= 15 N) grasps.
PEAK_N = (2.0, 18.0)
CAL_GRASPS = 60
SPLIT = "S1"


def log(msg: str) -> None:
    print(f"[interval_fit {time.strftime('%H:%M:%S')}] {msg}", flush=True)


@dataclass
class GraspReadings:
    """What the runtime reported on virtual grasps: force_n, truth_n (N), flags (int), low/high
    bounds (N) and interval state per reading (stale readings left out)."""

    force: np.ndarray
    truth: np.ndarray
    flags: np.ndarray
    low: np.ndarray
    high: np.ndarray
    state: list[str]
    source: str

    def contact(self) -> np.ndarray:
        """Readings with an estimate from the model (not no_contact, force finite)."""
        from tactile_force.edge.reading import Flags

        nc = (self.flags & int(Flags.NO_CONTACT)) != 0
        return ~nc & np.isfinite(self.force) & np.isfinite(self.truth)

    def no_contact(self) -> np.ndarray:
        from tactile_force.edge.reading import Flags

        return ((self.flags & int(Flags.NO_CONTACT)) != 0) & np.isfinite(self.truth)

    def saturated(self) -> np.ndarray:
        from tactile_force.edge.reading import Flags

        return (self.flags & int(Flags.SATURATED)) != 0


def grasp_readings(bundle, seed: int, n_grasps: int, split: str = SPLIT, peak_n: tuple[float, float] = PEAK_N,
                   progress: bool = True) -> GraspReadings:
    """Run ``bundle`` (path or Bundle) through ForceRuntime on ``n_grasps`` virtual DIGIT grasps
    of ``seed`` with the indenters of ``split``'s test part (``"all"``: the 18 paper indenters)."""
    from tactile_force.edge import ContactGate, ForceRuntime, OnnxForceModel, RuntimeOptions, Sensor
    from tactile_force.edge.reading import Flags
    from tactile_force.edge.synthetic import VirtualDigitSource, paper_indenter_names, paper_split

    indenters = list(paper_indenter_names()) if split == "all" else list(paper_split(split).test)
    src = VirtualDigitSource(seed=seed, n_grasps=n_grasps, indenters=indenters, peak_n=peak_n, name="virtual")
    model = OnnxForceModel(bundle, threads=1)
    rt = ForceRuntime([Sensor("virtual", src, ContactGate())], model, RuntimeOptions(deadline_ms=1e9))
    rows: list[tuple[float, float, int, float, float, str]] = []
    t0 = time.perf_counter()
    try:
        while not rt.finished:
            for r in rt.step():
                if r.flags & Flags.STALE or r.truth_n is None:
                    continue
                rows.append((r.force_n, r.truth_n, int(r.flags), r.force_low_n, r.force_high_n, r.interval.value))
            if progress and len(rows) % 2000 == 0 and rows:
                log(f"  {len(rows)} readings ({time.perf_counter() - t0:.0f} s)")
    finally:
        rt.close()
    a = np.array([r[:5] for r in rows], np.float64).reshape(-1, 5)
    desc = (f"{n_grasps} virtual DIGIT grasps through ForceRuntime (VirtualDigitSource seed {seed}, peaks "
            f"{peak_n[0]:g}-{peak_n[1]:g} N, " + ("all 18 paper indenters" if split == "all" else
                                                 f"{split} test indenters {', '.join(indenters)}")
            + f"; {len(rows)} readings)")
    return GraspReadings(a[:, 0], a[:, 1], a[:, 2].astype(np.int64), a[:, 3], a[:, 4], [r[5] for r in rows], desc)


def interval_from_readings(g: GraspReadings, coverage: float, model_sha256: str):
    """The conformal table from runtime readings: contact readings' (estimate, truth) pairs,
    saturated ones one-sided; no_contact readings' true forces for the gate-closed bound."""
    from tactile_force.edge.fitting.interval import fit_interval

    c = g.contact()
    return fit_interval(g.force[c], g.truth[c], coverage, data=g.source, model_sha256=model_sha256,
                        no_contact_truth=g.truth[g.no_contact()], saturated=g.saturated()[c])


def fit_bundle(path: Path, seed: int = CAL_SEED, n_grasps: int = CAL_GRASPS, coverage: float = 0.9,
               attempts: int = 3):
    """Fit the interval of the bundle at ``path`` and rewrite its model.json (ONNX untouched).

    The manifest is re-read right before writing; if the ONNX file's sha256 changed in the
    meantime, the fit is repeated on the new model (up to ``attempts`` times)."""
    from tactile_force.edge.bundle.store import load_bundle, write_bundle

    for _ in range(attempts):
        b = load_bundle(path)
        sha = b.manifest.sha256
        log(f"{path}: running {n_grasps} calibration grasps (seed {seed}) on model {sha[:12]}...")
        g = grasp_readings(b, seed, n_grasps)
        iv = interval_from_readings(g, coverage, sha)
        cur = load_bundle(path)  # re-read: another tool may have rewritten the bundle meanwhile
        if cur.manifest.sha256 != sha:
            log(f"{path}: model.onnx changed while fitting ({sha[:12]} -> {cur.manifest.sha256[:12]}); refitting")
            continue
        cur.manifest.interval = iv
        out = write_bundle(path, cur.onnx_path.read_bytes(), cur.manifest, overwrite=True)
        log(f"{path}: interval written ({iv.n} pairs, {len(iv.bins)} bins, no-contact bound "
            f"{iv.no_contact_high_n} N from {iv.no_contact_n} frames)")
        return out
    raise RuntimeError(f"{path}: model.onnx kept changing during {attempts} fits; run again when it is stable")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.interval_fit", description=__doc__.split("\n\n")[0])
    ap.add_argument("bundles", nargs="*", type=Path,
                    help="bundle folders (default: every bundle shipped in the package, edge/models/)")
    ap.add_argument("--grasps", type=int, default=CAL_GRASPS, help=f"calibration grasps (default {CAL_GRASPS})")
    ap.add_argument("--seed", type=int, default=CAL_SEED, help=f"VirtualDigitSource seed (default {CAL_SEED})")
    ap.add_argument("--coverage", type=float, default=0.9, help="stated coverage (default 0.9)")
    args = ap.parse_args(argv)
    if args.seed == REPORT_SEED:
        print(f"--seed {REPORT_SEED} is the report seed; fitting on it would make the report meaningless",
              file=sys.stderr)
        return 2
    from tactile_force.edge.scene import shipped_bundles

    for p in args.bundles or list(shipped_bundles().values()):
        fit_bundle(p, args.seed, args.grasps, args.coverage)
    return 0


if __name__ == "__main__":
    sys.exit(main())
