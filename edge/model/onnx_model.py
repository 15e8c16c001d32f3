"""ONNX Runtime inference on a verified model bundle (the bundle ladder that picks one by
its latency is :mod:`.ladder`).

:class:`OnnxForceModel` wraps one ORT session: intra-op threads configurable (default 1),
sequential execution, input buffers for up to :data:`~tactile_force.edge.frames.MAX_BATCH`
frames allocated once and bound to the session (IO binding: no per-call feed dict or output
allocation); batches 1 and 2 are bound and warmed at load, a larger batch (a runtime with
more sensors) is bound once, on its first call.
``predict(rgb (N,320,240,3) uint8, depth (N,320,240,1) uint8 | None) -> (N,) float32 N``.

A compact bundle's graph starts at the network resolution (manifest format 3: each input's
``reduction``, e.g. ``area-2x-steps`` x4 -> 80 x 60): ``predict`` reduces full-resolution
frames itself with :mod:`.reduce` straight into the bound input buffer, and
``predict_reduced`` takes images already reduced the same way (the runtime hands it the
image its contact gate reduced, so each frame is shrunk once). Full-resolution bundles
(reduction ``none``) read the frames as they are on both paths.
"""

from __future__ import annotations

import logging
import os
import threading

import numpy as np

from ..bundle.manifest import FrameReduction, InputKind, Reduction
from ..bundle.store import Bundle, load_bundle
from ..checks import expect
from ..errors import BundleError, FrameError, ModelClosedError
from ..frames import FRAME_COLS, FRAME_ROWS, MAX_BATCH, check_batch
from ..gate.reduce import FrameReducer
from ..limits import THREADS, bounds

RGB_SHAPE = (FRAME_ROWS, FRAME_COLS, 3)
DEPTH_SHAPE = (FRAME_ROWS, FRAME_COLS, 1)
#: Batches bound and warmed at load (both fingers of a gripper); larger ones are bound on first use.
LOAD_BATCH = 2


_log = logging.getLogger(__name__)


def session_options(threads: int = 1, exact_qdq: bool = False):
    """The onnxruntime session options every session of the package runs with: ``threads``
    intra-op threads, one inter-op thread, sequential execution, all graph optimisations,
    warnings off (an ``onnxruntime.SessionOptions``); ``exact_qdq``: an int8 QDQ graph runs unfused,
    as written (:mod:`.int8_host`: where the fused int8 kernels would saturate)."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = int(threads)
    so.inter_op_num_threads = 1
    so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    so.log_severity_level = 3
    if exact_qdq:
        so.add_session_config_entry("session.disable_quant_qdq", "1")
    return so


def bundle_session_options(bundle: Bundle, threads: int = 1):
    """:func:`session_options` for ``bundle``'s graph on this host: unfused where its int8 weights would
    saturate the fused kernels here (:func:`.int8_host.exact_qdq_needed`)."""
    return session_options(threads, exact_qdq=unfused_here(bundle))


def unfused_here(bundle: Bundle) -> bool:
    """Whether ``bundle``'s int8 graph runs unfused on this host (see :mod:`.int8_host`)."""
    from ..bundle.graph_facts import bundle_facts
    from .int8_host import exact_qdq_needed

    if bundle.manifest.precision.value not in ("int8-static", "int8-dynamic"):
        return False
    return exact_qdq_needed(bundle_facts(bundle.onnx_path, bundle.manifest.sha256).int8_weight_max)


class OnnxForceModel:
    """Force model on the CPU through ONNX Runtime.

    bundle: a verified :class:`Bundle` or a path to one (verified here: a bundle whose
    hash does not match is refused). threads: intra-op threads (1 = predictable latency
    next to other robot processes).
    """

    backend = "cpu"

    def __init__(self, bundle: Bundle | str | os.PathLike, threads: int = 1, warmup: int = 2,
                 calibrate: bool = True) -> None:
        import onnxruntime as ort

        expect(bundle, (Bundle, str, os.PathLike), "OnnxForceModel.bundle", "a Bundle or a bundle folder path",
               nonempty=True)
        expect(threads, int, "OnnxForceModel.threads", "an integer in [1, 1024] (ONNX Runtime intra-op threads)",
               **bounds(THREADS))
        expect(warmup, int, "OnnxForceModel.warmup", "an integer in [0, 10000] (warm-up runs at load)", ge=0, le=10_000)
        expect(calibrate, bool, "OnnxForceModel.calibrate")
        self.bundle = bundle if isinstance(bundle, Bundle) else load_bundle(bundle)
        m = self.bundle.manifest
        # Per-sensor force calibration (manifest force_calibration), applied to every output;
        # calibrate=False gives the raw estimate (what calibrate-force fits on).
        cal = getattr(m, "force_calibration", None)
        if cal is not None and cal.model_sha256 and cal.model_sha256 != m.sha256:
            raise BundleError(f"{self.bundle.path}: force_calibration was fitted for model sha256 "
                              f"{cal.model_sha256[:12]}..., not this bundle's {m.sha256[:12]}...; "
                              "re-run calibrate-force")
        self.calibration = cal if calibrate else None
        self.threads = int(threads)
        self._lock = threading.Lock()  # predict: the bound buffers are shared by every caller
        #: the int8 graph runs unfused on this host (its fused kernels would saturate: :mod:`.int8_host`)
        self.unfused = unfused_here(self.bundle)
        if self.unfused:
            _log.info("%s: this CPU adds int8 products in 16 bits (x86-64 without VNNI) and the graph's weights use "
                      "8 bits: onnxruntime's fused int8 kernels could saturate, so the graph runs unfused, as written "
                      "(the same forces as on any host; slower). A bundle quantized with 7-bit weights (tactile-force "
                      "quantize) keeps the fused kernels", self.bundle.path)
        try:
            self.session = ort.InferenceSession(str(self.bundle.onnx_path),
                                                session_options(self.threads, exact_qdq=self.unfused),
                                                providers=["CPUExecutionProvider"])
        except Exception as exc:  # ORT raises its own Fail/InvalidGraph types
            raise BundleError(f"{self.bundle.onnx_path}: ONNX Runtime cannot load the model ({exc})") from None
        check_graph_contract(self.bundle, self.session)
        rgb_spec, depth_spec = m.input(InputKind.RGB), m.input(InputKind.DEPTH)
        self.rgb_name = rgb_spec.name if rgb_spec else None  # None: D / Dmod (depth only)
        self.depth_name = depth_spec.name if depth_spec else None
        self.output_name = m.output.name
        # The network input record: (rows, cols, C) the graph reads and how a frame is reduced.
        self.rgb_shape = rgb_spec.network_shape if rgb_spec else None
        self.depth_shape = depth_spec.network_shape if depth_spec else None
        #: how predict reduces a full-resolution frame (the first input's; ``none``: full-res graph)
        first = rgb_spec or depth_spec
        self.reduction: FrameReduction = first.reduction if first is not None else FrameReduction()
        self._rgb_reducer = FrameReducer(rgb_spec.reduction, RGB_SHAPE) if rgb_spec else None
        self._depth_reducer = FrameReducer(depth_spec.reduction, DEPTH_SHAPE) if depth_spec else None
        # Allocated once for the largest batch (zeroed pages: rows never used are never
        # touched); predict reduces / copies into the first N rows. Output buffer and IO
        # binding of batch n: made at load for 1..LOAD_BATCH, for a larger n on its first call.
        self._rgb = np.zeros((MAX_BATCH, *self.rgb_shape), np.uint8) if self.rgb_shape else None
        self._depth = np.zeros((MAX_BATCH, *self.depth_shape), np.uint8) if self.depth_shape else None
        self._outs: list[np.ndarray | None] = [None] * MAX_BATCH
        self._bindings: list = [None] * MAX_BATCH
        for n in range(1, LOAD_BATCH + 1):
            self._prepare(n)
        for _ in range(warmup):
            for n in range(1, LOAD_BATCH + 1):
                self._run(n)

    @property
    def needs_depth(self) -> bool:
        return self.depth_name is not None

    @property
    def closed(self) -> bool:
        """True after :meth:`close` (predict then raises :class:`ModelClosedError`)."""
        return self.session is None

    def close(self) -> None:
        """Release the ONNX Runtime session (idempotent; waits for a predict in progress)."""
        with self._lock:
            self._bindings = []
            self.session = None

    def _feed(self, n: int) -> dict[str, np.ndarray]:
        feed: dict[str, np.ndarray] = {}
        if self._rgb is not None and self.rgb_name is not None:
            feed[self.rgb_name] = self._rgb[:n]
        if self._depth is not None and self.depth_name is not None:
            feed[self.depth_name] = self._depth[:n]
        return feed

    def _checked_output(self, n: int) -> np.ndarray:
        """One plain run at batch n; the output buffer (same shape and dtype) that n binds to."""
        out = np.asarray(self.session.run([self.output_name], self._feed(n))[0])
        if out.size != n:
            raise BundleError(f"{self.bundle.onnx_path}: output {self.output_name!r} has {out.size} values for a batch "
                              f"of {n}; expected one force (N) per frame")
        return np.empty_like(out)

    def _prepare(self, n: int):
        """Output buffer n and the IO binding of the first n rows of the input buffers to it
        (no copies), made once; returns the binding."""
        out = self._checked_output(n)
        binding = self.session.io_binding()
        for name, value in self._feed(n).items():
            binding.bind_cpu_input(name, value)
        binding.bind_output(self.output_name, "cpu", 0, out.dtype, list(out.shape), out.ctypes.data)
        self._outs[n - 1], self._bindings[n - 1] = out, binding
        return binding

    def _run(self, n: int) -> np.ndarray:
        """Forces (n,) float32 for the first n rows of the input buffers (a view: copy to keep)."""
        binding = self._bindings[n - 1]
        if binding is None:  # a batch larger than LOAD_BATCH, first call: bound once
            binding = self._prepare(n)
        self.session.run_with_iobinding(binding)
        out = self._outs[n - 1]
        assert out is not None  # made with the binding
        forces = out.reshape(-1) if out.dtype == np.float32 else out.astype(np.float32).reshape(-1)
        if self.calibration is not None:
            self.calibration.apply_inplace(forces)  # in the bound buffer, overwritten by the next run
        return forces

    def prewarm(self, n: int = 1) -> None:
        """One throw-away run of the session on what the last batch-``n`` call left in the
        bound input buffers (the runtime calls it shortly before a frame is due at a slow
        cadence, so the frame's call finds caches warm: edge/runtime/prewarm.py). Changes no
        answer already returned; does nothing for a batch not bound yet or after :meth:`close`."""
        with self._lock:
            if self.session is None or not 1 <= n <= len(self._bindings):
                return
            binding = self._bindings[n - 1]
            if binding is not None:
                self.session.run_with_iobinding(binding)

    def predict(self, rgb: np.ndarray | None, depth: np.ndarray | None = None) -> np.ndarray:
        """Forces in newtons, (N,) float32, for rgb (N,320,240,3) uint8 BGR and, for
        depth variants, depth (N,320,240,1) uint8, or depth images already at the network
        resolution (N, rows, cols, 1) (what a depth stage on the network grid makes, e.g.
        80 x 60). N is 1 to MAX_BATCH (16). D / Dmod bundles read only the depth images (rgb may then be None).
        A bundle whose graph starts at the network resolution reduces the frames here, once,
        by its recorded :attr:`reduction` (edge/gate/reduce.py) straight into the bound input buffer:
        ``predict(frames)`` equals ``predict_reduced(reduce_frames(frames, model.reduction))``.

        Thread-safe: one model may serve several threads or runtimes (two grippers); calls
        are serialised by a lock around fill + run + copy of the shared bound buffers (each
        call gets its own answer; uncontended cost well under a microsecond). For parallel
        inference give each runtime its own model. Raises :class:`ModelClosedError` after
        :meth:`close`."""
        with self._lock:
            if self.session is None:
                raise ModelClosedError(f"{self.bundle.path}: this OnnxForceModel was closed; load the bundle again "
                                       "(or pass owns_model=False to runtimes that share a model you close yourself)")
            return self._predict(rgb, depth)

    def predict_reduced(self, rgb: np.ndarray | None, depth: np.ndarray | None = None) -> np.ndarray:
        """Forces in newtons, (N,) float32, for images already at the network resolution.

        Parameters
        ----------
        rgb
            (N, rows, cols, 3) uint8 BGR: frames reduced by this bundle's ``reduction``
            (:attr:`rgb_shape`, e.g. (N, 80, 60, 3); for a full-resolution bundle the frames
            themselves). None for D / Dmod.
        depth
            Depth bundles: (N, rows, cols, 1) uint8 at :attr:`depth_shape`, or full-resolution
            (N, 320, 240, 1) depth images, which are reduced here.

        Returns
        -------
        numpy.ndarray
            (N,) float32 N; ``predict(frames)`` equals ``predict_reduced(reduce(frames))``.
        """
        with self._lock:
            if self.session is None:
                raise ModelClosedError(f"{self.bundle.path}: this OnnxForceModel was closed; load the bundle again "
                                       "(or pass owns_model=False to runtimes that share a model you close yourself)")
            return self._predict(rgb, depth, reduced=True)

    def _fill(self, x: np.ndarray | None, name: str, buf: np.ndarray, reducer: FrameReducer,
              full: tuple[int, int, int], net: tuple[int, int, int] | None, reduced: bool) -> int:
        """Check a batch and write it into the bound buffer (reducing full-resolution images
        once, straight into it); returns N."""
        # depth images made at the network resolution (a depth record with a reduction, the
        # depth stage's grid) are read as they are on both paths
        if (reduced or name == "depth") and net is not None and x is not None and x.ndim == 4 and x.shape[1:] == net:
            x = check_batch(x, name, net, MAX_BATCH)
            buf[:x.shape[0]] = x
            return x.shape[0]
        if reduced and name == "rgb" and net is not None and net != full:
            check_batch(x, name, net, MAX_BATCH)  # raises: says what shape was expected
        x = check_batch(x, name, full, MAX_BATCH)
        if reducer.reduction.method is Reduction.NONE:
            buf[:x.shape[0]] = x
        else:
            for i in range(x.shape[0]):
                reducer(x[i], out=buf[i])
        return x.shape[0]

    def _predict(self, rgb: np.ndarray | None, depth: np.ndarray | None, reduced: bool = False) -> np.ndarray:
        """:meth:`predict` without the lock and the closed check (the caller holds the lock)."""
        n = 0
        if self._rgb is not None and self._rgb_reducer is not None:
            n = self._fill(rgb, "rgb", self._rgb, self._rgb_reducer, RGB_SHAPE, self.rgb_shape, reduced)
        if self._depth is not None and self._depth_reducer is not None:
            if depth is None:
                raise FrameError(f"depth: this {self.bundle.variant} bundle needs a depth image (N,320,240,1) uint8")
            nd = self._fill(depth, "depth", self._depth, self._depth_reducer, DEPTH_SHAPE, self.depth_shape, reduced)
            if n and nd != n:
                raise FrameError(f"depth: batch {nd} but rgb batch {n}; expected one depth image per frame")
            n = nd
        return self._run(n).copy()


def _dims(shape: list) -> list[int | None]:
    return [d if isinstance(d, int) and d > 0 else None for d in shape]


def check_graph_contract(bundle: Bundle, session) -> None:
    """Refuse a graph that does not fit the frame contract its manifest declares.

    Every graph input must be a manifest input: uint8 NHWC (batch, rows, cols, C) with a
    dynamic batch, C = 3 for ``rgb``, 1 for ``depth``, and (rows, cols) the 320 x 240 frame
    reduced by the input's recorded ``reduction`` (80 x 60 for x4; 320 x 240 for ``none``);
    the output must be the manifest's float32 force. Raises :class:`BundleError` naming the
    input and what was expected.
    """
    m = bundle.manifest
    where = bundle.path
    graph_inputs = {i.name: i for i in session.get_inputs()}
    declared = {s.name: s for s in m.inputs}
    for name, spec in declared.items():
        gi = graph_inputs.get(name)
        if gi is None:
            raise BundleError(f"{where}: manifest input {name!r} is not in the ONNX graph "
                              f"({spec.kind.value}; graph inputs: {sorted(graph_inputs)}); "
                              "model and manifest do not match. "
                              f"A {m.variant.value!r} bundle needs the inputs {[s.kind.value for s in m.inputs]}")
        if gi.type != "tensor(uint8)":
            raise BundleError(f"{where}: graph input {name!r} is {gi.type}; the bundle contract is uint8")
        dims = _dims(list(gi.shape))
        rows, cols, ch = spec.network_shape
        want = [rows, cols, ch]
        if len(dims) != 4 or dims[1:] != want:
            red = spec.reduction
            how = ("the full frame" if red.method is Reduction.NONE
                   else f"the frame reduced by the manifest's {red.method.value} x{red.factor}")
            raise BundleError(f"{where}: graph input {name!r} has shape {list(gi.shape)}; the {spec.kind.value} "
                              f"contract is (batch, {rows}, {cols}, {ch}) NHWC ({how})"
                              + (f" (it looks transposed: {cols}x{rows})" if dims[1:3] == [cols, rows] else ""))
        if dims[0] is not None:
            raise BundleError(f"{where}: graph input {name!r} has a fixed batch of {dims[0]}; the runtime needs a "
                              f"dynamic batch (1 to {MAX_BATCH} frames, one per sensor): re-export the model")
    extra = sorted(set(graph_inputs) - set(declared))
    if extra:
        raise BundleError(f"{where}: the ONNX graph has input(s) {extra} that the manifest does not declare "
                          f"(declared: {sorted(declared)}); model and manifest do not match")
    outs = {o.name: o for o in session.get_outputs()}
    out = outs.get(m.output.name)
    if out is None:
        raise BundleError(f"{where}: manifest output {m.output.name!r} is not a graph output ({sorted(outs)})")
    if out.type not in ("tensor(float)", "tensor(float16)"):
        raise BundleError(f"{where}: graph output {m.output.name!r} is {out.type}; expected float32 newtons")
