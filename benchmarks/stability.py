"""Stability on stiff and extreme cases (stability.md), through the real runtime (gate, depth
stage, ORT).

Cases rendered with the virtual DIGIT: very rigid small indenters, soft objects, force
sweeps 0-1 N and 15-20 N, contacts at the gel's curved edge, dark / over-exposed / noisy /
drifting-LED frames, and float frames holding NaN / inf. For every bundle available
(every shipped bundle, found as ``edge/models/*/model.json``; trained reference bundles; and
random-weight bundles of every variant x precision, built with torch unless
``--shipped-only``) it counts non-finite model outputs (must be 0), checks the flags, the
share of monotone steps along force sweeps, and the int8 vs fp32 divergence at the extremes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .bundles import PRECISIONS, latency_bundle, trained_models
from .harness.frames import frame_pool, virtual_depth_stage
from .harness.latency import ModelConfig
from .harness.machine import command_line, describe_machine, header
from .harness.sources import ListSource
from .harness.stats import markdown_table


@dataclass
class Case:
    """A named list of frames (uint8 BGR, or anything for the bad-input case) with truth (N)."""

    name: str
    frames: list
    truth: list[float]
    expect: str = ""  # flag every reading must carry ('' = no rule)
    sweep: bool = False


@dataclass
class CaseReadings:
    """Readings of one bundle on one case."""

    raw: np.ndarray
    flags: list[list[str]]
    nonfinite: int
    flags_ok: float
    monotone: float = math.nan
    notes: list[str] = field(default_factory=list)


def build_cases(quick: bool = False) -> list[Case]:
    from tactile_force.edge.synthetic import ContactSpec, VirtualDigit, VirtualDigitOptions

    digit = VirtualDigit(VirtualDigitOptions(seed=3))
    rng = np.random.default_rng(3)
    step = 2 if quick else 1
    cases = []
    f = [float(x) for x in np.linspace(2, 14, 7 if quick else 13)]
    rigid = [digit.render(ContactSpec(n, (160, 120), stiffness="very_high"), x).frame
             for n in ("star_small", "ball_2.35mm", "cross_small") for x in f[::step]]
    cases.append(Case("rigid small indenters, 2-14 N", rigid, [x for _ in range(3) for x in f[::step]]))
    soft = [digit.render(ContactSpec(n, (160, 120), stiffness="medium"), x).frame
            for n in ("green_toy", "pringles", "circle_large") for x in f[::step]]
    cases.append(Case("soft objects (medium rigidity), 2-14 N", soft, [x for _ in range(3) for x in f[::step]]))
    for name, forces, expect in (("sweep 0-1 N", np.linspace(0.0, 0.99, 12), "no_contact|below_range"),
                                 ("sweep 15-20 N", np.linspace(15, 20, 11), "saturated"),
                                 ("sweep 1-15 N", np.linspace(1, 15, 29), "")):
        fr, tr = [], []
        for n in ("circle_large", "square_small", "sphere_4mm"):
            for x in forces[::step]:
                fr.append(digit.render(ContactSpec(n, (160, 120)), float(x)).frame)
                tr.append(float(x))
        cases.append(Case(name + " (3 indenters)", fr, tr, expect, sweep=True))
    edge = []
    for pos in ((12, 120), (308, 120), (160, 8), (160, 232), (20, 20)):
        for x in (4.0, 10.0):
            edge.append(digit.render(ContactSpec("circle_large", pos), x).frame)
    cases.append(Case("contacts at the curved edge", edge, [4.0, 10.0] * 5))
    base = [digit.render(ContactSpec("hexagon_large", (160, 120)), x) for x in (3.0, 8.0, 13.0)]
    cases.append(Case("dark frames (LED gain 0.02)", [digit.render(ContactSpec("hexagon_large", (160, 120)), 8.0,
                                                                  led_gain=(0.02, 0.02, 0.02)).frame] * 3,
                      [8.0] * 3, "invalid_input"))
    for gain in (4.0, 8.0):
        over = [np.clip(b.frame.astype(np.float32) * gain, 0, 255).astype(np.uint8) for b in base]
        cases.append(Case(f"over-exposed frames (x{gain:g}, clipped)", over, [b.force_n for b in base],
                          "invalid_input|saturated"))
    noisy = [np.clip(b.frame + rng.normal(0, 12, b.frame.shape), 0, 255).astype(np.uint8) for b in base]
    cases.append(Case("noisy frames (sigma 12 levels)", noisy, [b.force_n for b in base]))
    drift = []
    for g in np.linspace(0.9, 1.1, 8):
        drift.append(digit.render(ContactSpec("triangle_large", (160, 120)), 6.0, led_gain=(g, 2 - g, g)).frame)
    cases.append(Case("drifting LEDs (gain 0.9-1.1 per channel)", drift, [6.0] * len(drift)))
    bad = [np.full((320, 240, 3), np.nan, np.float32), np.full((320, 240, 3), np.inf, np.float32),
           base[1].frame.astype(np.float32)]
    bad[2][100:120, 100:120] = np.nan
    cases.append(Case("float frames with NaN / inf", bad, [8.0] * 3, "invalid_input"))
    return cases


def run_case(model, case: Case, background: np.ndarray, depth_factory=virtual_depth_stage) -> CaseReadings:
    """``case`` through a runtime over ``model``; ``depth_factory`` None: the depth stage the
    bundle's manifest records (as ``run`` builds it), else the virtual DIGIT's."""
    from tactile_force.edge import ContactGate, Flags, ForceRuntime, RuntimeOptions, Sensor

    gate = ContactGate()
    gate.capture_background(background)
    rt = ForceRuntime([Sensor("s", ListSource(case.frames, case.truth), gate)], model,
                      RuntimeOptions(deadline_ms=1e9), depth_factory=depth_factory)
    readings = []
    rt.run(on_reading=readings.append)
    raw = np.array([r.raw_force_n for r in readings])
    flags = [r.flags.names() for r in readings]
    skip = Flags.NO_CONTACT | Flags.INVALID_INPUT | Flags.BACKGROUND_MISMATCH  # the CNN did not run
    ran = np.array([not (r.flags & skip) and "model returned" not in r.detail for r in readings])
    nonfinite = sum(1 for r in readings if "model returned" in r.detail)
    nonfinite += int(np.count_nonzero(~np.isfinite(raw[ran])))
    ok = 1.0
    if case.expect:
        want = set(case.expect.split("|"))
        ok = float(np.mean([bool(want & set(f)) for f in flags])) if flags else math.nan
    out = CaseReadings(raw, flags, nonfinite, ok)
    if case.sweep:
        steps = []
        n_ind = 3
        per = len(raw) // n_ind
        for k in range(n_ind):
            seg = raw[k * per:(k + 1) * per]
            seg = seg[np.isfinite(seg)]
            steps += list(np.diff(seg) >= 0)
        out.monotone = float(np.mean(steps)) if steps else math.nan
    return out


#: what a bundle's weights are: shipped in edge/models, trained by the reference recipe, random (latency only)
SHIPPED, TRAINED, RANDOM = "shipped", "trained", "random"


def shipped_to_test() -> list[tuple[str, str, Path, str]]:
    """(``shipped NAME (variant)``, precision, path, SHIPPED) for every bundle in edge/models,
    found by its model.json (:func:`tactile_force.edge.scene.shipped_bundles`), the default first."""
    from tactile_force.edge.bundle.store import read_manifest
    from tactile_force.edge.scene import shipped_bundles

    out = []
    for name, path in shipped_bundles().items():
        m = read_manifest(path / "model.json")
        out.append((f"shipped {name} ({m.variant.value})", m.precision.value, path, SHIPPED))
    return out


def models_to_test(quick: bool, shipped_only: bool = False) -> list[tuple[str, str, Path, str]]:
    """(config, precision, bundle path, weights: SHIPPED / TRAINED / RANDOM) for every bundle
    stability runs on; ``shipped_only``: the shipped bundles alone (no torch, no cache)."""
    out = shipped_to_test()
    if shipped_only:
        return out
    for tm in trained_models():
        for p, path in tm.bundles.items():
            out.append((tm.config.name, p, path, TRAINED))
    variants = ("rgbmod", "rgbmod+d") if quick else ("rgbmod", "d", "dmod", "rgbmod+d")
    for v in variants:
        cfg = ModelConfig(v, 0.25, 4)
        for p in (("fp32", "int8-static") if quick else PRECISIONS):
            out.append((cfg.name, p, latency_bundle(cfg, p), RANDOM))
    return out


def run(args, argv) -> None:
    from tactile_force.edge import OnnxForceModel

    cases = build_cases(args.quick)
    bg = frame_pool().background
    results: dict[tuple[str, str, str], dict[str, CaseReadings]] = {}
    for cfg, prec, path, weights in models_to_test(args.quick, getattr(args, "shipped_only", False)):
        model = OnnxForceModel(path, threads=1)
        # a shipped bundle reads through the depth stage its manifest records, as `run` builds it
        depth = None if weights == SHIPPED and model.bundle.manifest.depth is not None else virtual_depth_stage
        try:
            results[(cfg, prec, weights)] = {c.name: run_case(model, c, bg, depth) for c in cases}
        finally:
            model.close()
        tot = sum(o.nonfinite for o in results[(cfg, prec, weights)].values())
        print(f"stability {cfg} {prec} {weights}: non-finite {tot}", flush=True)
    rows, total_nonfinite = [], 0
    for (cfg, prec, weights), per in results.items():
        trained = weights != RANDOM
        nf = sum(o.nonfinite for o in per.values())
        total_nonfinite += nf
        row = [cfg, prec, weights, nf]
        for c in cases:
            o = per[c.name]
            if c.expect:
                row.append(f"{o.flags_ok:.0%}" if (trained or "invalid_input" in c.expect) else
                           f"({o.flags_ok:.0%})")
        for c in cases:
            if c.sweep:
                mono = per[c.name].monotone
                txt = "-" if not math.isfinite(mono) else f"{mono:.0%}"
                row.append(txt if trained or txt == "-" else f"({txt})")
        rows.append(row)
    hdr = ["config", "precision", "weights", "non-finite outputs"]
    hdr += [f"flags right: {c.name}" for c in cases if c.expect]
    hdr += [f"monotone steps: {c.name}" for c in cases if c.sweep]
    # int8 vs fp32 at the extremes
    div_rows = []
    for (cfg, prec, weights), per in results.items():
        if prec != "int8-static" or (cfg, "fp32", weights) not in results:
            continue
        ref = results[(cfg, "fp32", weights)]
        cells = [cfg, weights]
        for c in cases:
            if c.name.startswith(("sweep 0-1", "sweep 15-20", "rigid", "soft")):
                a, b = per[c.name].raw, ref[c.name].raw
                ok = np.isfinite(a) & np.isfinite(b)
                cells.append(f"{np.abs(a[ok] - b[ok]).max():.3f} N" if ok.any() else "-")
        div_rows.append(cells)
    div_hdr = ["config", "weights"] + [f"max abs int8-fp32: {c.name}" for c in cases
                                       if c.name.startswith(("sweep 0-1", "sweep 15-20", "rigid", "soft"))]
    case_rows = [[c.name, len(c.frames), c.expect.replace("|", " or ") or "-"] for c in cases]
    m = describe_machine()
    verdict = "PASS" if total_nonfinite == 0 else "FAIL"
    text = header("Stability on stiff and extreme cases", command_line(argv), m, NOTE) + "\n".join([
        f"**Non-finite model outputs over every case, bundle and precision: {total_nonfinite} ({verdict}).**", "",
        "## Cases", "", markdown_table(["case", "frames", "every reading must be flagged"], case_rows), "",
        "## Per bundle", "", markdown_table(hdr, rows), "",
        "## int8 vs fp32 divergence (raw model output, N)", "", markdown_table(div_hdr, div_rows), "",
    ])
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "stability.md").write_text(text)
    print(f"wrote {args.out / 'stability.md'}; non-finite outputs: {total_nonfinite}")


NOTE = """Every frame goes through the real runtime (ForceRuntime: exposure check, contact gate,
depth stage for depth bundles, ONNX Runtime, clamping and flags). Flags are judged per
reading: 'no_contact|below_range' means either is right (a 0.3 N press may not open the
gate). Random-weight bundles (latency bundles) say nothing about accuracy, so their force
flags and monotonicity are shown in (parentheses) and only their non-finite counts and
input-validation flags (dark, NaN/inf) matter; trained bundles are the reference recipe's;
shipped bundles are those in edge/models (each read through the depth stage its manifest
records, as `run` reads it).
Over-exposed frames: the runtime flags an all-white mean as invalid_input; a partly
clipped frame is expected to read saturated (gel saturation seen) or invalid_input."""
