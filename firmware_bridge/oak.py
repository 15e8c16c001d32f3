"""Run a bundle's force model on a Luxonis OAK (depthai v3), host-fed.

Frames go host -> input queue -> NeuralNetwork node (the compiled model of an NN Archive)
-> output queue -> host. :class:`OakForceModel` is a
:class:`~tactile_force.edge.runtime.options.ForceModel` with the CPU backend's ``predict``
signature, so the runtime wraps it in the same ForceReading and latency accounting.

No device attached: depthai would search for about 11 s before raising; here the
available devices are listed first (about 0.5 s) and
:class:`~tactile_force.edge.errors.AcceleratorUnavailableError` is raised at once, which a
runtime catches to fall back to the CPU backend.
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass
from datetime import timedelta
from pathlib import Path

import numpy as np
from tactile_force.edge.bundle.force_calibration import ForceCalibration
from tactile_force.edge.bundle.manifest import FrameReduction, InputKind
from tactile_force.edge.bundle.store import Bundle, load_bundle
from tactile_force.edge.errors import (
    AcceleratorUnavailableError,
    FrameError,
    MissingExtraError,
    ModelClosedError,
    require,
)
from tactile_force.edge.frames import FRAME_SHAPE, check_batch
from tactile_force.edge.gate.reduce import FrameReducer
from tactile_force.edge.runtime.options import ForceModelBase


@dataclass
class OakOptions:
    """archive: NN Archive (.tar.xz) built by :func:`build_nn_archive` around the compiled model;
    device_id: the OAK's device id / MxId / IP (None = the first available);
    timeout_s: longest wait for one result before the device counts as gone."""

    archive: str | os.PathLike
    device_id: str | None = None
    timeout_s: float = 2.0


def _depthai():
    try:
        return require("depthai", "oak", "the OAK backend")
    except MissingExtraError as exc:
        raise AcceleratorUnavailableError(str(exc)) from exc


def available_oaks(dai=None) -> list:
    """DeviceInfo of every OAK depthai can see now (USB and network; about 0.5 s)."""
    dai = dai or _depthai()
    return list(dai.Device.getAllAvailableDevices())


class OakForceModel(ForceModelBase):
    """A bundle's model running on an OAK: ``predict(rgb, depth=None) -> (N,) float32 N``.

    Single-input variants only (rgbmod: BGR frames; d/dmod: depth images); a two-input
    graph (rgbmod+d) raises AcceleratorUnavailableError so the runtime uses the CPU.

    As a :class:`~tactile_force.edge.runtime.options.ForceModel`: ``predict`` reads full
    frames and reduces them itself (``reduction`` is ``none``: the runtime never hands it the
    gate's reduced image, :meth:`predict_reduced` is :meth:`predict`); no force calibration
    is applied (``calibration`` None).
    """

    def __init__(self, bundle: Bundle | str | os.PathLike, options: OakOptions) -> None:
        self.bundle = bundle if isinstance(bundle, Bundle) else load_bundle(bundle)
        self.options = options
        self._lock = threading.Lock()  # predict: one reused input frame and one queue pair for every caller
        m = self.bundle.manifest
        if len(m.inputs) != 1:
            raise AcceleratorUnavailableError(
                f"bundle {self.bundle.name}: variant {m.variant!r} has {len(m.inputs)} inputs; the OAK backend "
                "runs single-input graphs (rgbmod, d, dmod): use the CPU backend")
        self._spec = m.inputs[0]
        #: the force calibration applied to the output: none (the network's force as it is)
        self.calibration: ForceCalibration | None = None
        #: ``none``: :meth:`predict` takes full frames (a graph at the network resolution gets
        #: them reduced here, on the host)
        self.reduction = FrameReduction()
        #: the RGB images :meth:`predict_reduced` reads (full frames); None for d / dmod
        self.rgb_shape: tuple[int, int, int] | None = FRAME_SHAPE if self._spec.kind == InputKind.RGB else None
        # A graph at the network resolution (manifest inputs[].reduction): frames are reduced
        # here, once, as OnnxForceModel.predict reduces them (edge/gate/reduce.py).
        self._reducer = (FrameReducer(self._spec.reduction, (*FRAME_SHAPE[:2], self._spec.channels))
                         if self._spec.reduction.factor > 1 else None)
        archive = Path(options.archive)
        if not archive.is_file():
            raise AcceleratorUnavailableError(f"{archive}: NN Archive not found (build it with "
                                              "tactile_force.firmware_bridge.build_nn_archive)")
        dai = self._dai = _depthai()
        infos = available_oaks(dai)
        if options.device_id is not None:
            infos = [i for i in infos if options.device_id in (i.getDeviceId(), getattr(i, "name", None))]
        if not infos:
            wanted = f" with id {options.device_id}" if options.device_id else ""
            raise AcceleratorUnavailableError(
                f"no OAK device{wanted} available (depthai {getattr(dai, '__version__', '?')} searched USB and "
                "network): plug one in, check 'tactile-force devices' and the udev rule, or run on the CPU backend")
        try:
            self._device = dai.Device(infos[0])
            self._pipeline = dai.Pipeline(self._device)
            nn = self._pipeline.create(dai.node.NeuralNetwork)
            nn.setNNArchive(dai.NNArchive(str(archive)))
            self._in = nn.input.createInputQueue()
            self._out = nn.out.createOutputQueue()
            self._pipeline.start()
        except RuntimeError as exc:
            raise AcceleratorUnavailableError(f"OAK {infos[0].getDeviceId()}: cannot start the model from "
                                              f"{archive} ({exc})") from None
        gray = self._spec.kind == "depth"
        self._type = dai.ImgFrame.Type.GRAY8 if gray else (
            dai.ImgFrame.Type.BGR888p if self._spec.layout.upper() == "NCHW" else dai.ImgFrame.Type.BGR888i)
        self._frame = dai.ImgFrame()  # reused: setCvFrame copies into its buffer
        self.device_id = infos[0].getDeviceId()
        self.last_inference_ms = 0.0

    @property
    def needs_depth(self) -> bool:
        """True for depth variants: the runtime must run its depth stage and pass ``depth``."""
        return self.bundle.manifest.needs_depth

    def _check(self, batch: np.ndarray | None, name: str, depth: bool) -> np.ndarray:
        if batch is None:
            raise FrameError(f"{name}: required by variant {self.bundle.variant!r}, got None")
        return check_batch(batch, name, (*FRAME_SHAPE[:2], 1) if depth else FRAME_SHAPE)

    def predict(self, rgb: np.ndarray | None, depth: np.ndarray | None = None) -> np.ndarray:
        """Forces in N, shape (N,) float32, for rgb (N,320,240,3) uint8 BGR or, for d/dmod
        bundles, depth (N,320,240,1) uint8 (rgb may then be None), as the CPU backend.
        Thread-safe (calls are serialised: the queues pair each input with the next output);
        raises :class:`ModelClosedError` after :meth:`close`."""
        with self._lock:
            if self.closed:
                raise ModelClosedError(f"{self.bundle.path}: this OakForceModel was closed; open the device again")
            return self._predict(rgb, depth)

    @property
    def closed(self) -> bool:
        """True after :meth:`close`."""
        return getattr(self, "_device", None) is None

    def _predict(self, rgb: np.ndarray | None, depth: np.ndarray | None) -> np.ndarray:
        if self._spec.kind == "depth":
            batch = self._check(depth, "depth", True)
        else:
            batch = self._check(rgb, "rgb", False)
        out = np.empty(len(batch), np.float32)
        timeout = timedelta(seconds=self.options.timeout_s)
        start = time.perf_counter()
        for i, img in enumerate(batch):
            if self._reducer is not None:
                img = self._reducer(img)
            self._frame.setCvFrame(img[..., 0] if img.shape[-1] == 1 else img, self._type)
            self._frame.setSequenceNum(i)
            self._in.send(self._frame)
            msg = self._out.get(timeout)
            if msg is None:
                raise AcceleratorUnavailableError(f"OAK {self.device_id}: no result within {self.options.timeout_s} s "
                                                  "(device gone or pipeline stalled)")
            name = self.bundle.manifest.output.name
            tensor = msg.getTensor(name) if msg.hasLayer(name) else msg.getFirstTensor()
            out[i] = float(np.asarray(tensor, dtype=np.float32).reshape(-1)[0])
        self.last_inference_ms = (time.perf_counter() - start) * 1e3
        return out

    def close(self) -> None:
        """Stop the pipeline and release the device (idempotent; waits for a predict in progress)."""
        with self._lock:
            self._close()

    def _close(self) -> None:
        pipeline = getattr(self, "_pipeline", None)
        if pipeline is not None:
            pipeline.stop()
            self._pipeline = None
        device = getattr(self, "_device", None)
        if device is not None:
            device.close()
            self._device = None

    def __enter__(self) -> OakForceModel:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
