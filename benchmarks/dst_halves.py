"""The depth stage's DST-I by its even and odd halves against the dense sine-matrix products
(dst_halves.md): what the depth stage executes per reading each way (callgrind), and how far the
readings of the shipped depth bundles move (the maintainers' rule: every force within 1e-4 N and
every flag, contact decision and interval state the same) over virtual grasps and every real DIGIT
recording of the shared data.

    python -m benchmarks.dst_halves --out docs/benchmarks
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

READINGS = 100


def _dense_solve(solver, d: np.ndarray) -> np.ndarray:
    """The solve as the dense products made it before the halves (float32 S_r @ d @ S_c)."""
    from tactile_force.edge.depth.poisson import _eigenvalues
    from tactile_force.edge.depth.sine_halves import sine_matrix

    n_r, n_c = d.shape
    lam = _eigenvalues(n_r, np.float64)[:, None] + _eigenvalues(n_c, np.float64)[None, :]
    inv = (1.0 / (lam * (2.0 * (n_r + 1)) * (2.0 * (n_c + 1)))).astype(solver.dtype)
    s_r, s_c = sine_matrix(n_r).astype(solver.dtype), sine_matrix(n_c).astype(solver.dtype)
    spec = (s_r @ d) @ s_c
    spec *= inv
    return (s_r @ spec) @ s_c


class _Dense:
    """solve_divergence with preallocated dense matrices and buffers (the code before the halves)."""

    def __init__(self, solver) -> None:
        from tactile_force.edge.depth.poisson import _eigenvalues
        from tactile_force.edge.depth.sine_halves import sine_matrix

        n_r, n_c = solver.shape[0] - 1, solver.shape[1] - 1
        lam = _eigenvalues(n_r, np.float64)[:, None] + _eigenvalues(n_c, np.float64)[None, :]
        self.inv = (1.0 / (lam * (2.0 * (n_r + 1)) * (2.0 * (n_c + 1)))).astype(np.float32)
        self.s_r = np.ascontiguousarray(sine_matrix(n_r).astype(np.float32))
        self.s_c = np.ascontiguousarray(sine_matrix(n_c).astype(np.float32))
        self.tmp = np.empty((n_r, n_c), np.float32)
        self.spec = np.empty((n_r, n_c), np.float32)

    def __call__(self, d: np.ndarray) -> np.ndarray:
        np.matmul(self.s_r, d, out=self.tmp)
        np.matmul(self.tmp, self.s_c, out=self.spec)
        self.spec *= self.inv
        np.matmul(self.s_r, self.spec, out=self.tmp)
        np.matmul(self.tmp, self.s_c, out=self.spec)
        return self.spec


def worker(argv: list[str]) -> int:
    """Under callgrind: the shipped D bundle's depth stage on the gate's reduced contact images,
    N times with the dense products, N times by halves, each in its own segment."""
    import cv2
    from tactile_force.edge.bundle.manifest import InputKind  # noqa: F401 - the stage's imports first
    from tactile_force.edge.runtime.depth_factory import build_depth_stage
    from tactile_force.edge.scene import shipped_bundles

    from .harness.client_requests import Segment, on_valgrind
    from .instructions import _gate

    cv2.setNumThreads(1)
    on_valgrind()
    z = np.load(argv[0])
    n = int(argv[1])
    from tactile_force.edge import load_bundle

    bundle = load_bundle(shipped_bundles()["d"])
    stage = build_depth_stage(None, bundle.manifest)
    gate = _gate(z["background"])
    pairs = []
    for f in z["rgb"]:
        g = gate.update(f)
        assert g.contact and g.reduced is not None
        pairs.append((g.reduced.copy(), g.reduced_mask.copy()))
    halves = stage.solver.solve_divergence
    dense = _Dense(stage.solver)
    for name, solve in (("dense", dense), ("halves", halves)):
        stage.solver.solve_divergence = solve  # type: ignore[method-assign]
        for k in range(5):
            stage.process(*pairs[k % len(pairs)], checked=True)
        with Segment(name):
            for k in range(n):
                stage.process(*pairs[k % len(pairs)], checked=True)
    return 0


def _readings(bundle: Path, background: list[np.ndarray], frames: list[np.ndarray]) -> list[tuple]:
    from tactile_force.edge import ContactGate
    from tactile_force.edge.model.onnx_model import OnnxForceModel
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor

    from .harness.sources import ListSource

    gate = ContactGate()
    if background:
        gate.capture_background(background)
    rt = ForceRuntime([Sensor("s", ListSource(frames), gate)], OnnxForceModel(bundle, threads=1),
                      RuntimeOptions(deadline_ms=1e6, prewarm=False))
    out = []
    try:
        while not rt.finished:
            out += [(r.frame_index, r.force_n, int(r.flags), r.interval.value, r.contact_area_px, r.detail)
                    for r in rt.step()]
    finally:
        rt.close()
    return out


def _cases() -> dict[str, tuple[list[np.ndarray], list[np.ndarray]]]:
    import cv2
    from tactile_force.edge.synthetic.source import VirtualDigitSource

    from .harness.data import digit_backgrounds
    from .harness.paths import shared_data

    src = VirtualDigitSource(seed=3, n_grasps=3, render_ahead=0)
    virtual = []
    while (tf := src.read()) is not None:
        virtual.append(tf.frame)
    src.close()
    out = {"virtual grasps (seed 3, 3 grasps, 60 fps)": ([], virtual)}
    bgs = digit_backgrounds()
    for name in ("aurova_digit_grasp", "aurova_digit_grasp_heldout"):
        images = sorted(shared_data(name, "images").glob("*.png"), key=lambda p: int(p.stem))
        out[name] = ([bgs["aurova_background_b"]], [cv2.imread(str(p)) for p in images])
    presses = sorted(shared_data("fots_digit", "ball_presses").glob("*.png"))
    out["fots_digit ball presses"] = ([bgs["fots_digit_bg"]], [cv2.imread(str(p)) for p in presses])
    return out


def run(out: Path) -> int:
    from tactile_force.edge.depth.poisson import PoissonSolver
    from tactile_force.edge.scene import shipped_bundles

    from .harness import callgrind
    from .harness.machine import describe_machine
    from .harness.paths import source_commit
    from .instructions import _env, _frames_file

    t0 = time.monotonic()
    bundles = {k: v for k, v in shipped_bundles().items() if k in ("d", "rgbmod_d")}
    cases = _cases()
    rows = []
    halves = PoissonSolver.solve_divergence
    for b, path in bundles.items():
        for c, (bg, frames) in cases.items():
            PoissonSolver.solve_divergence = _dense_solve  # type: ignore[assignment]
            want = _readings(path, bg, frames)
            PoissonSolver.solve_divergence = halves  # type: ignore[method-assign]
            got = _readings(path, bg, frames)
            moved = [abs(g[1] - w[1]) for g, w in zip(got, want) if not np.isnan(g[1]) and g[1] != w[1]]
            other = sum((g[0], *g[2:]) != (w[0], *w[2:]) for g, w in zip(got, want))
            rows.append(f"| {b} | {c} | {len(got)} | {len(moved)} | {max(moved, default=0.0):.2e} | "
                        f"{sum(m > 1e-4 for m in moved)} | {other} |")
            print(rows[-1], flush=True)
    with tempfile.TemporaryDirectory(prefix="dst-halves-") as d:
        tmp = Path(d)
        frames = _frames_file(tmp)
        prof = callgrind.run_segments([sys.executable, "-m", "benchmarks.dst_halves", "--worker", str(frames),
                                       str(READINGS)], tmp / "cg.out",
                                      {**_env(), "TACTILE_FORCE_KERNELS": "compile"})
    dense_i, halves_i = prof["dense"].total / READINGS, prof["halves"].total / READINGS
    page = f"""# The depth stage's DST-I by halves

Command: `python -m benchmarks.dst_halves --out docs/benchmarks`

Commit: {source_commit()}

Machine: {describe_machine()}

The Poisson solve of the compact depth bundles (79 x 59 interior of the 80 x 60 grid) applies the DST-I as
dense products with the sine matrices. By its even and odd halves (S[j, n-1-k] = (-1)^j S[j, k]: even outputs
read only x[k] + x[n-1-k], odd ones only x[k] - x[n-1-k]) the same transform takes half the multiply-adds. The
maintainers allowed such a change where every force stays within 1e-4 N of today's and every flag, contact
decision and interval state is the same.

## Instructions per reading (the depth stage alone, the shipped D bundle, callgrind, {READINGS} readings)

| DST-I | instructions (M) per reading |
|---|---|
| dense products | {dense_i / 1e6:.3f} |
| by halves | {halves_i / 1e6:.3f} |
| change | {(halves_i - dense_i) / 1e6:+.3f} ({100 * (halves_i / dense_i - 1):+.0f} %) |

## Readings, halves against dense (ForceRuntime, one sensor, warm-ups off)

| bundle | recording | readings | forces that moved | largest move (N) | moved > 1e-4 N | other fields differ |
|---|---|---|---|---|---|---|
""" + "\n".join(rows) + f"""

Measured in {time.monotonic() - t0:.0f} s.
"""
    out.mkdir(parents=True, exist_ok=True)
    (out / "dst_halves.md").write_text(page)
    print(out / "dst_halves.md")
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--worker"]:
        return worker(argv[1:])
    p = argparse.ArgumentParser(prog="python -m benchmarks.dst_halves")
    p.add_argument("--out", type=Path, default=Path("out/benchmarks"))
    return run(p.parse_args(argv).out)


if __name__ == "__main__":
    sys.exit(main())
