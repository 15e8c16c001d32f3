"""Frames (and forces when labelled) for parity checks, calibration and error reports.

Two on-disk sources:
  * a dataset in the authors' layout (``images/N.png``, ``filt_img_depth/depth_img_N.png``,
    ``forces/force_N.txt``), paired by N; gives forces for RE/MAE;
  * a plain folder of PNGs: colour frames for rgbmod, grayscale depth images for d/dmod.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from tactile_force.edge.bundle.manifest import FrameReduction, Manifest, Reduction
from tactile_force.edge.data.dataset import AuthorsDataset
from tactile_force.edge.errors import DatasetError, TactileForceError
from tactile_force.edge.frames import FRAME_SHAPE
from tactile_force.edge.gate.reduce import reduce_frames
from tactile_force.edge.report.progress import progress

from .zoo import VARIANT_INPUTS, check_variant


class CalibrationError(TactileForceError, ValueError):
    """Calibration / parity frames are missing, unreadable, too few or the wrong shape."""


@dataclass
class CalibrationData:
    """Input batches by graph input name, each (N, 320, 240, C) uint8; forces (N,) in N or None.

    'rgb' is BGR (C=3), 'depth' is the 8-bit filtered depth image (C=1).
    """

    inputs: dict[str, np.ndarray]
    forces: np.ndarray | None
    source: str
    ids: list[str]

    def __len__(self) -> int:
        return len(self.ids)

    def batches(self, batch_size: int = 1) -> Iterator[dict[str, np.ndarray]]:
        """Yield feed dicts of up to ``batch_size`` frames."""
        for i in range(0, len(self), batch_size):
            yield {k: v[i:i + batch_size] for k, v in self.inputs.items()}

    def reduced(self, reduction: FrameReduction) -> CalibrationData:
        """The same frames reduced to the network resolution as the runtime reduces them
        (edge/gate/reduce.py), for graphs that start there; forces, source and ids unchanged."""
        if reduction.method is Reduction.NONE:
            return self
        return CalibrationData({k: reduce_frames(v, reduction) for k, v in self.inputs.items()}, self.forces,
                               self.source, self.ids)

    def for_manifest(self, manifest: Manifest) -> CalibrationData:
        """The frames as the bundle's graph reads them (reduced when its inputs record a reduction)."""
        by_name = {s.name: s.reduction for s in manifest.inputs}
        if all(r.method is Reduction.NONE for r in by_name.values()):
            return self
        return CalibrationData({k: v if by_name.get(k) is None or by_name[k].method is Reduction.NONE
                                else reduce_frames(v, by_name[k]) for k, v in self.inputs.items()},
                               self.forces, self.source, self.ids)

    def subset(self, n: int) -> CalibrationData:
        """The first ``n`` frames."""
        return CalibrationData({k: v[:n] for k, v in self.inputs.items()},
                               None if self.forces is None else self.forces[:n], self.source, self.ids[:n])

    @classmethod
    def from_path(cls, path: str | os.PathLike, variant: str, limit: int | None = None,
                  min_frames: int = 1, show_progress: bool = False) -> CalibrationData:
        """Read frames for ``variant`` from an authors'-layout dataset or a folder of PNGs."""
        variant = check_variant(variant)
        names = VARIANT_INPUTS[variant]
        if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 1):
            raise CalibrationError(f"limit={limit!r}: expected a whole number of frames >= 1 (None = all frames)")
        root = Path(path)
        if not root.exists():
            raise CalibrationError(f"{root}: calibration/parity folder not found")
        if not root.is_dir() or not os.access(root, os.R_OK | os.X_OK):
            raise CalibrationError(f"{root}: not a readable folder (check the path and its permissions)")
        if (root / "images").is_dir():
            data = cls._from_dataset(root, names, limit, show_progress)
        else:
            data = cls._from_pngs(root, names, limit, show_progress)
        if len(data) < min_frames:
            raise CalibrationError(
                f"{root}: only {len(data)} usable frame(s); at least {min_frames} are needed "
                "(use a few hundred frames covering the force range for good int8 calibration)")
        return data

    @classmethod
    def _from_dataset(cls, root: Path, names: tuple[str, ...], limit: int | None, show: bool) -> CalibrationData:
        try:
            ds = AuthorsDataset(root, require_depth="depth" in names)
        except DatasetError as exc:
            raise CalibrationError(str(exc)) from None
        ids = ds.ids[:limit] if limit is not None else ds.ids
        rgb, depth, forces = [], [], []
        for n in progress(ids, desc=f"reading {root.name}", enabled=show):
            try:
                s = ds.load(n)
            except DatasetError as exc:
                raise CalibrationError(str(exc)) from None
            if "rgb" in names:
                rgb.append(_checked(s.frame, ds.image_path(n), 3))
            if "depth" in names:
                depth.append(_checked(s.depth, ds.depth_path(n), 1))
            forces.append(s.force_n)
        inputs = {}
        if rgb:
            inputs["rgb"] = np.stack(rgb)
        if depth:
            inputs["depth"] = np.stack(depth)
        return cls(inputs, np.asarray(forces, dtype=np.float64), f"authors' dataset {root}", [str(i) for i in ids])

    @classmethod
    def _from_pngs(cls, root: Path, names: tuple[str, ...], limit: int | None, show: bool) -> CalibrationData:
        if len(names) != 1:
            raise CalibrationError(
                f"{root}: variant needs both RGB frames and depth images; give a dataset in the authors' layout "
                "(images/N.png + filt_img_depth/depth_img_N.png + forces/force_N.txt)")
        kind = names[0]
        files = sorted(p for p in root.iterdir() if p.suffix.lower() == ".png" and p.is_file())
        if not files:
            raise CalibrationError(f"{root}: no .png frames found (expected 320x240 "
                                   + ("BGR frames" if kind == "rgb" else "8-bit depth images") + ")")
        files = files[:limit] if limit is not None else files
        frames = []
        for f in progress(files, desc=f"reading {root.name}", enabled=show):
            img = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)  # never converted: a colour PNG is not a depth image
            if img is None:
                raise CalibrationError(f"{f}: cannot read image (unreadable, empty or truncated PNG)")
            frames.append(_checked(img, f, 3 if kind == "rgb" else 1))
        return cls({kind: np.stack(frames)}, None, f"PNG folder {root}", [f.name for f in files])


def _checked(img: np.ndarray | None, path: Path, c: int) -> np.ndarray:
    if img is None:
        raise CalibrationError(f"{path}: image missing")
    if img.ndim == 2:
        img = img[:, :, None]
    got = img.shape[2] if img.ndim == 3 else 0
    if got != c:
        what = ("the model takes single-channel 8-bit depth images (filt_img_depth/depth_img_N.png), "
                f"not {'colour frames' if got >= 3 else f'{got}-channel images'}; give the depth images or "
                "a dataset in the authors' layout") if c == 1 else \
               (f"the model takes 3-channel BGR colour frames, not {got}-channel images (a grey or "
                "depth image is not a tactile frame)")
        raise CalibrationError(f"{path}: {got}-channel image; {what}")
    want = (FRAME_SHAPE[0], FRAME_SHAPE[1], c)
    if img.shape != want or img.dtype != np.uint8:
        raise CalibrationError(f"{path}: image is {img.shape} {img.dtype}; expected {want} uint8 "
                               "(DIGIT portrait frames, 320 rows x 240 columns)")
    return img


def random_frames(variant: str, n: int = 4, seed: int = 0) -> CalibrationData:
    """Deterministic uniform-random uint8 frames, for a parity check when no data is given."""
    rng = np.random.default_rng(seed)
    inputs = {k: rng.integers(0, 256, (n, FRAME_SHAPE[0], FRAME_SHAPE[1], 3 if k == "rgb" else 1), dtype=np.uint8)
              for k in VARIANT_INPUTS[check_variant(variant)]}
    return CalibrationData(inputs, None, f"{n} random uint8 frames (seed {seed})", [str(i) for i in range(n)])
