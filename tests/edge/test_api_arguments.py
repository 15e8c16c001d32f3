"""The Python API refuses a wrong argument at construction, naming the parameter and what was
expected, with a TactileForceError that is also a TypeError / ValueError (never an
AttributeError or "'<' not supported" from deep inside, never silently accepted)."""

from __future__ import annotations

import dataclasses
import math
import typing

import numpy as np
import pytest
from tactile_force import edge
from tactile_force.edge import (
    AuthorsDataset,
    CameraSource,
    ContactGate,
    CsvWriter,
    ForceRuntime,
    GateOptions,
    JsonlWriter,
    OnnxForceModel,
    ReplayFolderSource,
    RuntimeOptions,
    Sensor,
    StdoutWriter,
    VideoFileSource,
    VirtualDigitSource,
    default_bundle_path,
)
from tactile_force.edge.data.dataset import AuthorsDatasetWriter
from tactile_force.edge.depth import DepthOptions, DepthStage, MaxDeformationBaseline, NormalLUT
from tactile_force.edge.errors import ArgumentTypeError, OptionsError, TactileForceError
from tactile_force.edge.synthetic import ContactSpec, DatasetOptions, IndenterSplit, VirtualDigit, VirtualDigitOptions

from tests.conftest import ListSource


@pytest.fixture(scope="module")
def model():
    m = OnnxForceModel(default_bundle_path())
    yield m
    m.close()


def _sensor() -> Sensor:
    return Sensor("left", ListSource([]), ContactGate())


#: (what the user wrote, the call, the words the error must hold: the parameter and what was expected)
CASES: dict[str, tuple[typing.Callable[..., object], str]] = {
    "ForceRuntime(model=None)": (lambda m, d: ForceRuntime([_sensor()], model=None),
                                 r"ForceRuntime\.model=None: expected a force model with predict\(\)"),
    "ForceRuntime(sensors=a_sensor)": (lambda m, d: ForceRuntime(_sensor(), m),
                                       r"ForceRuntime\.sensors: got one Sensor; expected a list of 1 to 16 Sensor"),
    "ForceRuntime(sensors=['left'])": (lambda m, d: ForceRuntime(["left"], m),
                                       r"ForceRuntime\.sensors\[0\]='left': expected a Sensor"),
    "ForceRuntime(options=dict)": (lambda m, d: ForceRuntime([_sensor()], m, options={"threads": 2}),
                                   r"ForceRuntime\.options=\{'threads': 2\}: expected a RuntimeOptions or None"),
    "ForceRuntime(clock=0)": (lambda m, d: ForceRuntime([_sensor()], m, clock=0),
                              r"ForceRuntime\.clock=0: expected a callable"),
    "Sensor(source='folder')": (lambda m, d: Sensor("left", "folder", ContactGate()),
                                r"Sensor\.source='folder': expected a frame source"),
    "Sensor(gate=GateOptions())": (lambda m, d: Sensor("left", ListSource([]), GateOptions()),
                                   r"Sensor\.gate=GateOptions\(.*: expected a ContactGate"),
    "Sensor(name=3)": (lambda m, d: Sensor(3, ListSource([]), ContactGate()), r"Sensor\.name=3: expected a non-empty"),
    "GateOptions(threshold='x')": (lambda m, d: GateOptions(threshold="x"),
                                   r"GateOptions\.threshold='x': expected a number > 0 and < 255, got str"),
    "GateOptions(threshold=nan)": (lambda m, d: GateOptions(threshold=math.nan),
                                   r"GateOptions\.threshold=nan: expected a finite number"),
    "GateOptions(background_frames=True)": (lambda m, d: GateOptions(background_frames=True),
                                            r"GateOptions\.background_frames=True: expected an integer in \[1, 10000\], got bool"),
    "GateOptions(downscale=2.5)": (lambda m, d: GateOptions(downscale=2.5),
                                   r"GateOptions\.downscale=2\.5: expected an integer in \[1, 16\], got float"),
    "ContactGate('x')": (lambda m, d: ContactGate("x"), r"ContactGate\.options='x': expected a GateOptions or None"),
    "OnnxForceModel(threads='2')": (lambda m, d: OnnxForceModel(default_bundle_path(), threads="2"),
                                    r"OnnxForceModel\.threads='2': expected an integer in \[1, 1024\]"),
    "OnnxForceModel(None)": (lambda m, d: OnnxForceModel(None),
                             r"OnnxForceModel\.bundle=None: expected a Bundle or a bundle folder path"),
    "RuntimeOptions(grabbers='yes')": (lambda m, d: RuntimeOptions(grabbers="yes"),
                                       r"RuntimeOptions\.grabbers='yes': expected true or false or None"),
    "DepthOptions(mapping=None)": (lambda m, d: DepthOptions(None), r"DepthOptions\.mapping=None: expected a path"),
    "DepthOptions(levels_per_px='5')": (lambda m, d: DepthOptions("m.npz", levels_per_px="5"),
                                        r"DepthOptions\.levels_per_px='5': expected a number > 0"),
    "DepthStage('m.npz')": (lambda m, d: DepthStage("m.npz"), r"DepthStage\.options='m\.npz': expected a DepthOptions"),
    "CameraSource(device=1.5)": (lambda m, d: CameraSource(1.5), r"CameraSource\.device=1\.5: expected a camera index"),
    "CameraSource(fourcc='MJPG')": (lambda m, d: CameraSource(0, fourcc="MJPG"),
                                    r"CameraSource\.fourcc='MJPG': expected a tuple of FOURCC codes"),
    "ReplayFolderSource(None)": (lambda m, d: ReplayFolderSource(None),
                                 r"ReplayFolderSource\.path=None: expected a replay folder path"),
    "ReplayFolderSource(fps='60')": (lambda m, d: ReplayFolderSource(d, fps="60"),
                                     r"ReplayFolderSource\.fps='60': expected a frame rate in \[0\.01, 10000\] per second, or None"),
    "ReplayFolderSource(shape=(320, 240))": (lambda m, d: ReplayFolderSource(d, shape=(320, 240)),
                                             r"ReplayFolderSource\.shape=\(320, 240\): expected \(rows, cols, 3\)"),
    "VideoFileSource(3)": (lambda m, d: VideoFileSource(3), r"VideoFileSource\.path=3: expected a video file path"),
    "VirtualDigitSource(n_grasps=True)": (lambda m, d: VirtualDigitSource(n_grasps=True),
                                          r"VirtualDigitSource\.n_grasps=True: expected an integer in \[1, 10000\]"),
    "VirtualDigitSource(fps=inf)": (lambda m, d: VirtualDigitSource(fps=math.inf),
                                    r"VirtualDigitSource\.fps=inf: expected a finite frame rate in \[0\.01, 10000\]"),
    "VirtualDigit('x')": (lambda m, d: VirtualDigit("x"), r"VirtualDigit\.options='x': expected a VirtualDigitOptions"),
    "VirtualDigitOptions(noise_std_bgr=(1, 2))": (lambda m, d: VirtualDigitOptions(noise_std_bgr=(1, 2)),
                                                  r"VirtualDigitOptions\.noise_std_bgr=\(1, 2\): expected \(B, G, R\)"),
    "ContactSpec(3)": (lambda m, d: ContactSpec(3), r"ContactSpec\.indenter=3: expected an indenter name"),
    "DatasetOptions(n=2.5)": (lambda m, d: DatasetOptions(n=2.5), r"DatasetOptions\.n=2\.5: expected an integer >= 1"),
    "CsvWriter(None)": (lambda m, d: CsvWriter(None), r"CsvWriter\.path=None: expected a file path"),
    "JsonlWriter(fsync='yes')": (lambda m, d: JsonlWriter(d / "r.jsonl", fsync="yes"),
                                 r"JsonlWriter\.fsync='yes': expected true or false"),
    "StdoutWriter(stream='err')": (lambda m, d: StdoutWriter(stream="err"),
                                   r"StdoutWriter\.stream='err': expected a text stream with write\(\)"),
    "StdoutWriter(every=0)": (lambda m, d: StdoutWriter(every=0), r"StdoutWriter\.every=0: expected an integer >= 1"),
    "MaxDeformationBaseline('x')": (lambda m, d: MaxDeformationBaseline("x"),
                                    r"MaxDeformationBaseline\.coeffs='x': expected polynomial coefficients"),
    "NormalLUT([[0.0]], ...)": (lambda m, d: NormalLUT([[0.0]], 4.0, np.zeros((320, 240, 3), np.uint8)),
                                r"NormalLUT\.lut=\[\[0\.0\]\]: expected a \(B, B, B, 3\) float array"),
    "IndenterSplit(val=3)": (lambda m, d: IndenterSplit("s", ("a",), 3, ()),
                             r"IndenterSplit\.val=3: expected a tuple of a string"),
    "AuthorsDataset(None)": (lambda m, d: AuthorsDataset(None), r"AuthorsDataset\.root=None: expected a dataset folder"),
    "AuthorsDatasetWriter(start_id=-1)": (lambda m, d: AuthorsDatasetWriter(d / "ds", start_id=-1),
                                          r"AuthorsDatasetWriter\.start_id=-1: expected a sample number >= 0"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_wrong_argument_is_refused_at_construction_naming_it(case, model, tmp_path):
    call, words = CASES[case]
    with pytest.raises(TactileForceError, match=words) as info:
        call(model, tmp_path)
    assert isinstance(info.value, (TypeError, ValueError))  # code catching those keeps working
    assert not isinstance(info.value, AttributeError)


def test_wrong_types_are_type_errors_and_values_out_of_range_value_errors():
    with pytest.raises(ArgumentTypeError) as info:
        GateOptions(threshold="x")
    # a TypeError, and a ValueError too: options that raised ValueError for a wrong type before still are
    assert isinstance(info.value, TypeError) and isinstance(info.value, ValueError)
    with pytest.raises(OptionsError) as out_of_range:
        GateOptions(threshold=300.0)
    assert isinstance(out_of_range.value, ValueError) and not isinstance(out_of_range.value, TypeError)
    with pytest.raises(OptionsError, match=r"ForceRuntime\.sensors: 17 sensors; expected 1 to 16: every frame needs "
                                           r"its own contact-gate pass .* serve more with a second ForceRuntime"):
        ForceRuntime([_sensor() for _ in range(17)], object())
    with pytest.raises(OptionsError, match=r"ForceRuntime\.sensors: 0 sensors; expected 1 to 16$"):
        ForceRuntime([], object())


class _PredictOnly:
    """A backend written against the old, thin protocol: predict() and needs_depth only."""

    needs_depth = False

    def predict(self, rgb, depth=None):
        return np.zeros(len(rgb), np.float32)


def test_a_model_lacking_a_force_model_member_is_refused_naming_what_is_missing(model):
    from tactile_force.edge.checks import protocol_members
    from tactile_force.edge.runtime import ForceModel

    with pytest.raises(ArgumentTypeError, match=r"ForceRuntime\.model=.*_PredictOnly lacks calibration, bundle, "
                                                r"reduction, rgb_shape, closed, predict_reduced, close \(ForceModel "
                                                r"declares .*\)") as info:
        ForceRuntime([_sensor()], _PredictOnly())
    assert isinstance(info.value, TactileForceError)
    attrs, methods = protocol_members(ForceModel)
    assert set(attrs) == {"bundle", "calibration", "reduction", "rgb_shape", "needs_depth", "closed"}
    assert set(methods) == {"predict", "predict_reduced", "close"}
    for name in attrs + methods:  # the CPU backend has every member
        assert hasattr(model, name), name

    class NotCallable(_PredictOnly):
        bundle = calibration = rgb_shape = None
        reduction = model.reduction
        closed = False
        predict_reduced = close = "not a method"

    with pytest.raises(ArgumentTypeError, match=r"NotCallable lacks predict_reduced, close \("):
        ForceRuntime([_sensor()], NotCallable())


def test_a_depth_factory_making_no_depth_stage_is_refused_at_construction():
    from tactile_force.edge.scene import shipped_bundles

    if "d" not in shipped_bundles():
        pytest.skip("no shipped depth bundle")
    d = OnnxForceModel(shipped_bundles()["d"])
    with pytest.raises(ArgumentTypeError, match=r"ForceRuntime\.depth_factory\(\)=.*: expected a DepthStage"):
        ForceRuntime([_sensor()], d, depth_factory=lambda: "a stage")
    d.close()


def test_numpy_numbers_are_numbers_and_bool_is_not_a_count():
    opts = GateOptions(threshold=np.float32(12.5), background_frames=np.int64(3), downscale=np.int32(2))
    assert ContactGate(opts).options.background_frames == 3
    assert RuntimeOptions(deadline_ms=np.float64(5.0), threads=np.int64(2)).threads == 2
    assert DepthOptions("m.npz", mapping_step=np.int64(2)).mapping_step == 2
    for bad in (True, np.bool_(True)):
        with pytest.raises(ArgumentTypeError, match=r"GateOptions\.relearn_frames=(np\.)?True_?: expected an "
                                                    r"integer in \[0, 1000000\]"):
            GateOptions(relearn_frames=bad)


#: the options dataclasses exported from tactile_force.edge, with the arguments they require
_REQUIRED = {"DepthOptions": {"mapping": "m.npz"}, "ContactSpec": {"indenter": "circle_small"}}


def _options_classes() -> list[type]:
    """The options dataclasses of the public API: tactile_force.edge and its depth and synthetic packages."""
    import importlib

    out = []
    for mod in (edge, importlib.import_module("tactile_force.edge.depth"),
                importlib.import_module("tactile_force.edge.synthetic")):
        for name in mod.__all__:
            obj = getattr(mod, name)
            if (isinstance(obj, type) and dataclasses.is_dataclass(obj) and name.endswith(("Options", "Spec"))
                    and obj not in out):
                out.append(obj)
    return out


def test_every_exported_options_dataclass_checks_every_field_type():
    """The mechanism, not the examples: each field of every exported options dataclass refuses
    a value of another type, naming Class.field."""
    classes = _options_classes()
    assert {c.__name__ for c in classes} >= {"GateOptions", "RuntimeOptions", "DepthOptions", "VirtualDigitOptions",
                                              "DatasetOptions", "ContactSpec"}
    for cls in classes:
        required = _REQUIRED.get(cls.__name__, {})
        cls(**required)  # the defaults are valid
        for f in dataclasses.fields(cls):
            wrong = object()  # of no annotated type: not a number, string, path, bool, option class
            with pytest.raises(ArgumentTypeError, match=rf"{cls.__name__}\.{f.name}=") as info:
                cls(**{**required, f.name: wrong})
            assert isinstance(info.value, TypeError)


def test_scene_messages_keep_naming_the_key_when_the_options_refuse(tmp_path):
    """GateOptions checks its cross-field rules when made; inside a scene the error still names
    the file and the key."""
    from tactile_force.edge.errors import SceneError
    from tactile_force.edge.scene import load_scene

    p = tmp_path / "s.toml"
    p.write_text('[[sensor]]\nsource = "virtual"\ngate = { on_area_frac = 0.001, off_area_frac = 0.002 }\n')
    with pytest.raises(SceneError, match=rf"^{p}: sensor\[0\]\.gate: GateOptions\.on_area_frac=0\.001"):
        load_scene(p)
