"""The reference recipe's data: the synthetic dataset rendered once and cached, its held-out
test split, the whole dataset in memory (:class:`Arrays`), the frames reduced to the network
resolution and the depth images made as the runtime makes them (benchmarks/reference.py)."""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .harness.data import Labelled
from .harness.frames import VIRTUAL_DEPTH_MAPPING, network_reduction, virtual_depth_stage
from .harness.paths import cache_dir
from .reference_configs import ABOVE_RANGE_SHARE, DATASET_N, DATASET_SEED, SPLIT, TrainConfig, log, network_resolution


def reduce_frames(frames: np.ndarray, k: int) -> np.ndarray:
    """(N, 320, 240, C) uint8 -> (N, 320/k, 240/k, C) uint8 with the network reduction."""
    from tactile_force.edge.gate.reduce import reduce_frames as _reduce

    return _reduce(frames, network_reduction(k))


def dataset_root() -> Path:
    return cache_dir() / f"synth-n{DATASET_N}-seed{DATASET_SEED}-above{ABOVE_RANGE_SHARE:g}"


def dataset_options():
    """The reference dataset's :class:`tactile_force.edge.synthetic.DatasetOptions`."""
    from tactile_force.edge.synthetic import DatasetOptions, ForceDistribution

    return DatasetOptions(n=DATASET_N, seed=DATASET_SEED, progress=False,
                          forces=ForceDistribution(above_fraction=ABOVE_RANGE_SHARE))


def heldout_test_split(limit: int = 0) -> list[tuple[int, np.ndarray, float, dict]]:
    """The held-out test split (:data:`SPLIT`'s test indenters) of the reference dataset,
    rendered alone by the virtual DIGIT (seconds, no torch, no cache): (sample number, frame
    320 x 240 x 3 uint8 BGR, force N, metadata), bit for bit the frames :func:`ensure_dataset`
    writes for them; ``limit`` > 0: the first ``limit`` only."""
    from tactile_force.edge.synthetic import paper_split, render_samples

    out = render_samples(dataset_options(), paper_split(SPLIT).test)
    return out[:limit] if limit else out


def ensure_dataset() -> Path:
    """Generate the synthetic dataset once (authors' layout + meta.jsonl)."""
    from tactile_force.edge.synthetic import generate_dataset

    root = dataset_root()
    if (root / "DONE").is_file():
        return root
    tmp = root.with_name(root.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)
    log(f"generating {DATASET_N} synthetic frames into {root}")
    summary = generate_dataset(tmp, dataset_options())
    log(f"generated at {summary.frames_per_s:.0f} frames/s")
    (tmp / "DONE").write_text(json.dumps(summary.as_dict(), default=str, indent=2))
    shutil.rmtree(root, ignore_errors=True)
    os.replace(tmp, root)
    return root


@dataclass
class Arrays:
    """The whole dataset in memory: rgb (N,320,240,3) uint8 BGR, depth (N,320,240,1)
    uint8 or None, force (N,) N, ids, metadata, and split part per sample."""

    rgb: np.ndarray
    force: np.ndarray
    ids: list[int]
    meta: list[dict]
    part: np.ndarray
    depth: np.ndarray | None = None
    #: network-resolution inputs by k: {"rgb": (N,320/k,240/k,3), "depth": (N,320/k,240/k,1)}
    reduced: dict[int, dict[str, np.ndarray]] | None = None

    def select(self, part: str) -> np.ndarray:
        return np.flatnonzero(self.part == part)

    def inputs(self, cfg: TrainConfig, idx: np.ndarray) -> dict[str, np.ndarray]:
        """The network inputs of config ``cfg`` for samples ``idx`` (raw uint8 frames; at
        the network resolution for :func:`network_resolution` configs)."""
        if network_resolution(cfg):
            assert self.reduced is not None and cfg.k in self.reduced, "load_arrays(depth_downscales=...)"
            src = self.reduced[cfg.k]
        else:
            src = {"rgb": self.rgb, **({"depth": self.depth} if self.depth is not None else {})}
        return {n: src[n][idx] for n in _input_names(cfg)}

    def full_inputs(self, cfg: TrainConfig, idx: np.ndarray) -> dict[str, np.ndarray]:
        """The inputs as export and quantization take them (320 x 240 frames, reduced by the
        graph's recorded reduction): the full-resolution rgb frames, and for network-resolution
        configs each grid depth image repeated over its k x k block (any box-average reduction
        gives it back exactly)."""
        if not network_resolution(cfg):
            return self.inputs(cfg, idx)
        out = {}
        for n in _input_names(cfg):
            if n == "rgb":
                out[n] = self.rgb[idx]
            else:
                assert self.reduced is not None
                out[n] = np.repeat(np.repeat(self.reduced[cfg.k]["depth"][idx], cfg.k, axis=1), cfg.k, axis=2)
        return out


def _input_names(cfg: TrainConfig) -> list[str]:
    return (["rgb"] if cfg.variant in ("rgbmod", "rgbmod+d") else []) + (["depth"] if cfg.variant != "rgbmod" else [])


def load_arrays(root: Path, with_depth: bool = False, depth_downscales: tuple[int, ...] = ()) -> Arrays:
    from tactile_force.edge import AuthorsDataset
    from tactile_force.edge.synthetic import paper_split, split_ids

    cache = root / "arrays.npz"
    if cache.is_file():
        z = np.load(cache, allow_pickle=False)
        rgb, force, ids = z["rgb"], z["force"], z["ids"].tolist()
    else:
        ds = AuthorsDataset(root)
        ids = list(ds.ids)
        rgb = np.stack([ds.load(n).frame for n in ids])
        force = ds.forces()
        np.savez(cache, rgb=rgb, force=force, ids=np.array(ids))
    ds_meta = AuthorsDataset(root).meta
    parts = split_ids(ds_meta, paper_split(SPLIT))
    part = np.full(len(ids), "other", dtype=object)
    pos = {n: i for i, n in enumerate(ids)}
    for name, members in parts.items():
        for n in members:
            part[pos[n]] = name
    arrays = Arrays(rgb=rgb, force=force.astype(np.float32), ids=ids, meta=[ds_meta.get(n, {}) for n in ids],
                    part=part.astype(str))
    if with_depth:
        arrays.depth = depth_images(root, arrays.rgb, 1, arrays.meta)
    arrays.reduced = {}
    for k in depth_downscales:
        arrays.reduced[k] = {"rgb": reduce_frames(arrays.rgb, k),
                             "depth": depth_images(root, arrays.rgb, k, arrays.meta)}
    return arrays


def depth_images(root: Path, rgb: np.ndarray, downscale: int = 1, meta: list[dict] | None = None) -> np.ndarray:
    """Depth images of every frame, made as the runtime makes them: the contact gate's
    mask + the depth stage with the virtual DIGIT's calibration
    (benchmarks/virtual_depth_calibration.py); (N,320,240,1) uint8, or at ``downscale`` k
    (N,320/k,240/k,1) made on the reduced frame. Cached next to the dataset."""
    from tactile_force.edge import ContactGate, GateOptions
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions

    cache = root / f"depth-s{downscale}.npy"  # v2: gate background rendered with each frame's LED gains
    skipped = 0
    if cache.is_file():
        return np.load(cache)
    log(f"computing depth images (downscale {downscale}) with the runtime's gate + depth stage "
        f"({VIRTUAL_DEPTH_MAPPING.name})")
    digit = VirtualDigit(VirtualDigitOptions())
    backgrounds: dict[tuple[float, ...], np.ndarray] = {}
    stage = virtual_depth_stage(downscale)
    out = np.zeros((rgb.shape[0], *stage.output_shape), np.uint8)
    for i, frame in enumerate(rgb):
        # the gate's background is the sensor's own no-contact frame, as a runtime learns it:
        # the virtual DIGIT rendered with this frame's LED gains (its grasp's)
        gain = tuple(float(v) for v in (meta[i].get("led_gain") if meta else None) or (1.0, 1.0, 1.0))
        if gain not in backgrounds:
            backgrounds[gain] = digit.render(None, 0.0, led_gain=gain, rng=np.random.default_rng(0)).frame
        gate = ContactGate()
        gate.capture_background([backgrounds[gain]])
        g = gate.update(frame)
        if g.mismatch or g.invalid:
            # judged from one frame the gate calls a very large press a mismatch; in a stream it
            # tracks a press that grew while it watched: take its mask with the judging off
            skipped += 1
            gate = ContactGate(GateOptions(trust=False))
            gate.capture_background([backgrounds[gain]])
            g = gate.update(frame)
        out[i] = stage.process(frame, g.mask).depth
    log(f"depth images: {skipped} of {len(out)} frames the gate judged a mismatch from one frame "
        "(mask taken with its judging off)")
    tmp = cache.with_name(cache.name + ".partial.npy")
    np.save(tmp, out)
    os.replace(tmp, cache)
    return out


def synthetic_test(with_depth: bool) -> Labelled:
    """The held-out-indenter test split of the reference dataset."""
    arrays = load_arrays(ensure_dataset(), with_depth=with_depth)
    idx = arrays.select("test")
    return Labelled(arrays.rgb[idx], arrays.depth[idx] if with_depth else None, arrays.force[idx].astype(np.float64),
                    f"synthetic test split ({SPLIT}, held-out indenters, {len(idx)} frames)")
