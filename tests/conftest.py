"""Shared test helpers: where the real sensor data lives, and a skip when it is absent."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from tactile_force.edge.bundle.manifest import ErrorReport, InputKind, InputSpec, Manifest, ModelOutputSpec, Provenance
from tactile_force.edge.bundle.store import write_bundle
from tactile_force.edge.frames import FrameSource, TimedFrame
from thread_guard import thread_guard  # noqa: F401 - autouse: a test may not leave a thread running

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("TACTILE_FORCE_SHARED_DATA", REPO.parent / "shared" / "data"))

#: Cyclone DDS on the loopback interface only (lo, no multicast, peer 127.0.0.1), set before any
#: DDS participant exists in the test process; .ci/run exports the same file.
CYCLONEDDS_LOOPBACK = REPO / "tests" / "cyclonedds_loopback.xml"
os.environ["CYCLONEDDS_URI"] = CYCLONEDDS_LOOPBACK.as_uri()


#: What the shared data is, where it comes from and how to point to it: the one reason every
#: test that needs it gives when it is absent.
SHARED_DATA_ABOUT = (
    "it holds real sensor data kept outside the repository (real DIGIT frames with forces and depth images "
    "from AUROVA-LAB, DIGIT backgrounds and ball presses, GelSight Mini and Wedge data; its README.md gives "
    "each file's source and licence); by default it is shared/data in the folder that holds the checkout: "
    "set TACTILE_FORCE_SHARED_DATA to the data folder when it is elsewhere"
)


def shared_data(*parts: str) -> Path:
    """Path under the shared data folder (``SHARED_DATA``); skips the test, saying what the data
    is and where it comes from, when it is absent."""
    p = SHARED_DATA.joinpath(*parts)
    if not p.exists():
        where = (f"the shared data folder {SHARED_DATA} is missing" if not SHARED_DATA.is_dir()
                 else f"{p} is missing from the shared data folder")
        pytest.skip(f"{where}: {SHARED_DATA_ABOUT}")
    return p


class ListSource(FrameSource):
    """A finite source over in-memory frames, each read once, with its true force (N; None =
    unknown); ``closed`` tells whether the runtime closed it. Timestamps are 0, the index is the
    frame's position."""

    name = "memory"

    def __init__(self, frames, truth=None) -> None:
        super().__init__()
        self.frames = list(frames)
        truth = [None] * len(self.frames) if truth is None else truth
        self.truth = [None if t is None else float(t) for t in truth]
        self.closed = False

    def read(self):
        i = self.stats.frames
        if i >= len(self.frames):
            return None
        self.stats.frames += 1
        return TimedFrame(self.frames[i], 0, i, self.truth[i])

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def aurova_dir() -> Path:
    """The 11 real DIGIT frames with forces (authors' layout)."""
    return shared_data("aurova_digit_grasp")


@pytest.fixture
def portraits(aurova_dir):
    """The first three real AUROVA DIGIT frames (320x240x3 uint8 BGR, portrait)."""
    from tactile_force.edge import AuthorsDataset

    data = AuthorsDataset(aurova_dir)
    return [data[i].frame for i in range(3)]


# -- test bundles: small real ONNX graphs (the 'mean model': force_n = scale * mean(rgb) / 255 + bias) ----
def mean_model_bytes(scale: float, bias: float, with_depth: bool, depth_scale: float = 0.0,
                     with_rgb: bool = True) -> bytes:
    """A tiny real ONNX graph: force = bias + scale * mean(rgb)/255 [+ depth_scale * mean(depth)/255]."""
    onnx = pytest.importorskip("onnx", reason="building test bundles needs the 'onnx' package (dev extra)")
    from onnx import TensorProto, helper

    nodes = [
        helper.make_node("Cast", ["rgb"], ["rgb_f"], to=TensorProto.FLOAT),
        helper.make_node("ReduceMean", ["rgb_f"], ["m"], axes=[1, 2, 3], keepdims=0),
        helper.make_node("Mul", ["m", "k"], ["mk"]),
        helper.make_node("Add", ["mk", "b"], ["f"]),
    ]
    inits = [helper.make_tensor("k", TensorProto.FLOAT, [], [scale / 255.0]),
             helper.make_tensor("b", TensorProto.FLOAT, [], [bias]),
             helper.make_tensor("shape", TensorProto.INT64, [2], [-1, 1])]
    inputs = [helper.make_tensor_value_info("rgb", TensorProto.UINT8, ["N", 320, 240, 3])]
    last = "f"
    if not with_rgb:  # D / Dmod graphs read only the depth image
        nodes = [helper.make_node("Constant", [], ["f"], value=helper.make_tensor("f0", TensorProto.FLOAT, [], [bias]))]
        inputs = []
    if with_depth:
        inputs.append(helper.make_tensor_value_info("depth", TensorProto.UINT8, ["N", 320, 240, 1]))
        nodes += [helper.make_node("Cast", ["depth"], ["d_f"], to=TensorProto.FLOAT),
                  helper.make_node("ReduceMean", ["d_f"], ["dm"], axes=[1, 2, 3], keepdims=0),
                  helper.make_node("Mul", ["dm", "kd"], ["dmk"]),
                  helper.make_node("Add", ["f", "dmk"], ["fd"])]
        inits.append(helper.make_tensor("kd", TensorProto.FLOAT, [], [depth_scale / 255.0]))
        last = "fd"
    nodes.append(helper.make_node("Reshape", [last, "shape"], ["force"]))
    graph = helper.make_graph(nodes, "mean_force", inputs,
                              [helper.make_tensor_value_info("force", TensorProto.FLOAT, ["N", 1])], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    return model.SerializeToString()


def mean_manifest(variant: str, name: str, error: ErrorReport | None = None) -> Manifest:
    inputs = [InputSpec("rgb", InputKind.RGB, [-1, 320, 240, 3])] if variant in ("rgbmod", "rgbmod+d") else []
    if variant != "rgbmod":
        inputs.append(InputSpec("depth", InputKind.DEPTH, [-1, 320, 240, 1], colour_order="GRAY"))
    return Manifest(variant=variant, precision="fp32", inputs=inputs, output=ModelOutputSpec("force", [-1, 1]),
                    name=name, error=error, provenance=Provenance(note="test mean model, not trained"))


@pytest.fixture(scope="session")
def make_bundle(tmp_path_factory):
    """make_bundle(name, variant='rgbmod', scale=20.0, bias=0.0, error=None) -> bundle folder."""
    root = tmp_path_factory.mktemp("bundles")

    def make(name: str, variant: str = "rgbmod", scale: float = 20.0, bias: float = 0.0,
             error: ErrorReport | None = None) -> Path:
        dest = root / name
        if not dest.exists():
            data = mean_model_bytes(scale, bias, variant != "rgbmod", depth_scale=5.0,
                                    with_rgb=variant in ("rgbmod", "rgbmod+d"))
            write_bundle(dest, data, mean_manifest(variant, name, error))
        return dest

    return make


@pytest.fixture(scope="session")
def rgb_bundle(make_bundle) -> Path:
    return make_bundle("mean_rgbmod")


# -- depth: real mapping files from the shared data, built once ----------------------------
@pytest.fixture(scope="session")
def paper_mlp_path():
    return shared_data("aurova_digit_depth_mlp.npz")


@pytest.fixture(scope="session")
def fots_lut_path(tmp_path_factory):
    """Our LUT calibrated on the real FOTS DIGIT ball presses (circles detected)."""
    import cv2
    from tactile_force.edge.depth.calibration import LUTOptions, Press, detect_press_circle, fit_lut

    folder = shared_data("fots_digit", "ball_presses")
    bg = cv2.imread(str(shared_data("digit_backgrounds", "fots_digit_bg.png")))
    presses = []
    for f in sorted(folder.glob("*.png"))[:24]:
        img = cv2.imread(str(f))
        c = detect_press_circle(img, bg)
        if c is not None:
            presses.append(Press(img, c, f.name))
    lut = fit_lut(presses, bg, 2.35 * 19.58, LUTOptions())
    return lut.save(tmp_path_factory.mktemp("lut") / "fots_lut.npz")


# -- deterministic timing and the mean model's expected output ------------------------------
def expected_force(frame: np.ndarray, scale: float = 20.0, bias: float = 0.0) -> float:
    return float(scale * frame.astype(np.float64).mean() / 255.0 + bias)


class FakeClock:
    """Deterministic monotonic clock (ns): each call advances by ``step_ns``; ``sleep``
    advances it too. Shared by the runtime and paced sources in timing tests."""

    def __init__(self, step_ns: int) -> None:
        self.t = 1_000_000_000
        self.step_ns = step_ns

    def __call__(self) -> int:
        self.t += self.step_ns
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += int(seconds * 1e9)


def compiled_kernels(*kinds: str):
    """Load the ``fast`` extra's compiled kernels of ``kinds`` ('gate', 'depth') in this test process,
    compiling those missing from numba's cache (seconds, once per environment); skips, naming the
    extra, where numba is not installed. Kernels once loaded stay in use in the process (the paths
    give the same values)."""
    pytest.importorskip("numba", reason="the compiled kernels are the 'fast' extra (numba), not installed here")
    from tactile_force.edge import compiled_path

    compiled_path.load(kinds)


@pytest.fixture
def kernel_mode():
    """Set the compiled-kernel mode for one test ('off': the OpenCV / numpy path); restored after."""
    from tactile_force.edge import compiled_path

    yield compiled_path.set_kernel_mode
    compiled_path.set_kernel_mode(None)
