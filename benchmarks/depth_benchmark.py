"""The depth benchmark page (docs/depth_benchmark.md): the depth stage at 320 x 240 on one core,
side by side with the DST-II port used by digit-depth / PyTouch / tactile-in-hand
(:mod:`benchmarks.harness.poisson_port`), and at the network resolution (80 x 60,
``DepthOptions(downscale=4)``, the compact depth bundles).

    python -m benchmarks.depth_benchmark [--repeats 200] [--write docs/depth_benchmark.md]

Needs ../shared/data (paper MLP, FOTS DIGIT ball presses) and SciPy (for the port).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from .harness.machine import describe_machine, header  # noqa: E402
from .harness.paths import shared_data  # noqa: E402
from .harness.poisson_port import port_solve  # noqa: E402


def _time(fn, repeats: int) -> float:
    fn()
    t = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        t.append(time.perf_counter() - t0)
    return float(np.median(t) * 1e3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--write", help="write the markdown table to this file")
    args = ap.parse_args()
    import cv2

    cv2.setNumThreads(1)
    from tactile_force.edge.depth import DepthOptions, DepthStage, PoissonSolver, forward_gradients
    from tactile_force.edge.depth.calibration import LUTOptions, Press, detect_press_circle, fit_lut

    H, W = 320, 240
    rows, cols = np.mgrid[0:H, 0:W].astype(np.float64)
    r = np.hypot(rows - 160, cols - 120)
    cap = np.where(r < 20, np.sqrt(np.maximum(40.0**2 - r**2, 0)) - np.sqrt(40.0**2 - 20**2), 0.0)
    gx, gy = forward_gradients(cap)
    gx32, gy32 = gx.astype(np.float32), gy.astype(np.float32)
    lines = []
    s32 = PoissonSolver((H, W), np.float32)
    s64 = PoissonSolver((H, W), np.float64)
    snp = PoissonSolver((H, W), np.float32, backend="numpy")
    rows_out = [
        ("DST-I exact, scipy.fft, float32", lambda: s32.solve(gx32, gy32), s32.solve(gx32, gy32)),
        ("DST-I exact, scipy.fft, float64", lambda: s64.solve(gx, gy), s64.solve(gx, gy)),
        ("DST-I exact, numpy rfft, float32", lambda: snp.solve(gx32, gy32), snp.solve(gx32, gy32)),
        ("DST-II port (pi k/(n+2)), float64", lambda: port_solve(gx, gy), port_solve(gx, gy)),
    ]
    lines.append("| Poisson solve, 320 x 240, 20 px cap (R 40 px) | ms (median) | peak error | max abs error (px) |")
    lines.append("|---|---|---|---|")
    for name, fn, out in rows_out:
        ms = _time(fn, args.repeats)
        lines.append(f"| {name} | {ms:.2f} | {out.max() / cap.max() - 1:+.2e} | {np.abs(out - cap).max():.2e} |")
    # the same cap on the 80 x 60 grid (heights in full-resolution px), its own discrete gradients
    small_cap = cap.reshape(80, 4, 60, 4).mean(axis=(1, 3))
    sgx, sgy = (g.astype(np.float32) for g in forward_gradients(small_cap))
    s_small = PoissonSolver((80, 60), np.float32)
    out = s_small.solve(sgx, sgy)
    ms = _time(lambda: s_small.solve(sgx, sgy), args.repeats)
    lines.append(f"| DST-I exact, scipy.fft, float32, 80 x 60 grid (network resolution) | {ms:.3f} | "
                 f"{out.max() / small_cap.max() - 1:+.2e} | {np.abs(out - small_cap).max():.2e} |")

    # Whole stage on real frames.
    import glob

    bg = cv2.imread(str(shared_data() / "digit_backgrounds" / "fots_digit_bg.png"))
    files = sorted(glob.glob(str(shared_data() / "fots_digit" / "ball_presses" / "*.png")))
    presses = []
    for f in files[:32]:
        img = cv2.imread(f)
        c = detect_press_circle(img, bg)
        if c is not None:
            presses.append(Press(img, c, f))
    lut_path = Path(tempfile.gettempdir()) / "depth_benchmark_fots_lut.npz"
    fit_lut(presses, bg, 2.35 * 19.58, LUTOptions()).save(lut_path)
    test = cv2.imread(files[-1])
    c = detect_press_circle(test, bg)
    mask = np.zeros((H, W), np.uint8)
    cv2.circle(mask, (int(c.cx), int(c.cy)), int(c.r * 1.2), 255, -1)
    full = np.full((H, W), 255, np.uint8)
    aur = cv2.imread(str(shared_data() / "aurova_digit_grasp" / "images" / "1516.png"))
    aur_mask = (cv2.imread(str(shared_data() / "aurova_digit_grasp" / "filt_img_depth" / "depth_img_1516.png"), 0) > 0)
    mlp = shared_data("aurova_digit_depth_mlp.npz")
    lut_stage = DepthStage(DepthOptions(lut_path))
    grid_stage = DepthStage(DepthOptions(lut_path, downscale=4))
    from tactile_force.edge.gate.reduce import default_reduction, reduce_frames

    test_small = reduce_frames(test[None], default_reduction(4))[0]
    mask_small = np.ascontiguousarray(mask[::4, ::4])
    mlp_stage = DepthStage(DepthOptions(mlp))
    paper = DepthStage(DepthOptions(mlp, mode="paper"))
    paper.set_reference([cv2.imread(str(shared_data() / "aurova_digit_grasp" / "images" / "1500.png"))])
    stage_rows = [
        (f"exact, our LUT, press mask ({np.count_nonzero(mask)} px)", lambda: lut_stage.process(test, mask)),
        ("exact, our LUT, full-frame mask (76800 px)", lambda: lut_stage.process(test, full)),
        (f"exact, paper MLP, contact mask ({np.count_nonzero(aur_mask)} px)", lambda: mlp_stage.process(aur, aur_mask)),
        ("paper-compatible, paper MLP on all pixels", lambda: paper.process(aur, aur_mask)),
        (f"network resolution (downscale 4): our LUT, 80x60 reduced frame + 80x60 press mask "
         f"({np.count_nonzero(mask_small)} px) -> 80x60x1", lambda: grid_stage.process(test_small, mask_small)),
        ("network resolution (downscale 4): full frame + full mask, reduced inside the stage",
         lambda: grid_stage.process(test, mask)),
    ]
    lines.append("")
    lines.append("| whole depth stage, 320 x 240 frame -> 320x240x1 uint8 (unless stated) | ms (median) |")
    lines.append("|---|---|")
    for name, fn in stage_rows:
        assert fn().ok
        lines.append(f"| {name} | {_time(fn, max(20, args.repeats // 4)):.2f} |")
    import scipy

    machine = describe_machine()
    notes = f"One thread (OMP/BLAS/OpenCV threads = 1); scipy {scipy.__version__}."
    text = "\n".join(lines)
    print(text)
    print(f"\nmachine: {machine.line()}; {machine.background_load}")
    if args.write:
        command = f"python -m benchmarks.depth_benchmark --repeats {args.repeats} --write {args.write}"
        Path(args.write).write_text(header("Depth stage benchmark", command, machine, notes) + "\n" + text + "\n")

if __name__ == "__main__":
    main()
