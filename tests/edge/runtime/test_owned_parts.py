"""A runtime owns its parts: a source, a contact gate or a depth stage (or the state inside one,
as a shallow copy shares it) given to two sensors is refused naming both; a source lacking
read() or close() is refused when the sensor is made; close() releases the model even when a
source's close() raises, and says which. Real ONNX Runtime (the shipped bundles), real gates
and depth stages; the sources are in-memory lists."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from tactile_force.edge import ContactGate, ForceRuntime, OnnxForceModel, Sensor
from tactile_force.edge.errors import ArgumentTypeError, OptionsError, SourceError, TactileForceError
from tactile_force.edge.gate.options import GateOptions
from tactile_force.edge.runtime.depth_factory import build_depth_stage
from tactile_force.edge.scene import default_bundle_path, shipped_bundles

from tests.conftest import ListSource


@pytest.fixture(scope="module")
def model():
    m = OnnxForceModel(default_bundle_path())
    yield m
    m.close()


def test_one_gate_under_two_sensors_is_refused_naming_both(model):
    gate = ContactGate()
    sensors = [Sensor("thumb", ListSource([]), gate), Sensor("index", ListSource([]), ContactGate()),
               Sensor("middle", ListSource([]), gate)]
    with pytest.raises(OptionsError, match=r"sensors 'thumb' and 'middle' share one gate \(ContactGate\)"):
        ForceRuntime(sensors, model, owns_model=False)
    assert not model.closed


def test_one_source_under_two_sensors_is_refused_naming_both(model):
    source = ListSource([])
    sensors = [Sensor("a", source, ContactGate()), Sensor("b", source, ContactGate())]
    with pytest.raises(OptionsError, match=r"sensors 'a' and 'b' share one source \(ListSource\)"):
        ForceRuntime(sensors, model, owns_model=False)


def test_a_shallow_copy_of_a_gate_shares_its_state_and_is_refused(model):
    gate = ContactGate()
    with pytest.raises(OptionsError, match=r"'a' and 'b' share one gate's _\w+ \(\w+, inside its ContactGate\)"):
        ForceRuntime([Sensor("a", ListSource([]), gate), Sensor("b", ListSource([]), copy.copy(gate))], model,
                     owns_model=False)


def test_gates_sharing_options_and_a_background_image_are_their_own(model):
    options = GateOptions()
    background = [np.full((320, 240, 3), 120, np.uint8)]
    gates = [ContactGate(options) for _ in range(3)]
    for g in gates:
        g.capture_background(background)  # one image handed to three gates: each keeps its own state
    rt = ForceRuntime([Sensor(f"s{k}", ListSource([]), g) for k, g in enumerate(gates)], model, owns_model=False)
    rt.close()


@pytest.mark.parametrize("make", ["same", "copy"])
def test_a_depth_factory_giving_one_stage_twice_is_refused(make):
    d = OnnxForceModel(shipped_bundles()["d"])
    stage = build_depth_stage(None, d.bundle.manifest if d.bundle is not None else None)
    factory = (lambda: stage) if make == "same" else (lambda: copy.copy(stage))
    sensors = [Sensor("a", ListSource([]), ContactGate()), Sensor("b", ListSource([]), ContactGate())]
    with pytest.raises(OptionsError, match=r"sensors 'a' and 'b' share one depth stage"):
        ForceRuntime(sensors, d, depth_factory=factory)
    assert all(s.depth is None for s in sensors)  # a refused runtime set nothing on the sensors
    ok = ForceRuntime(sensors, d, depth_factory=lambda: build_depth_stage(None, d.bundle.manifest))
    assert sensors[0].depth is not sensors[1].depth
    ok.close()
    assert d.closed


class NoClose:
    def read(self):
        return None


def test_a_source_without_close_is_refused_when_the_sensor_is_made():
    with pytest.raises(ArgumentTypeError, match=r"Sensor.source=.*NoClose lacks close \(FrameReader declares read, "
                                                r"close\)"):
        Sensor("a", NoClose(), ContactGate())  # type: ignore[arg-type]


def test_a_source_replaced_after_the_sensor_was_made_is_checked_by_the_runtime(model):
    s = Sensor("a", ListSource([]), ContactGate())
    s.source = object()  # type: ignore[assignment]
    with pytest.raises(ArgumentTypeError, match=r"ForceRuntime.sensors\[0\].source=.* lacks read, close"):
        ForceRuntime([s], model, owns_model=False)


class FailsToClose(ListSource):
    def close(self) -> None:
        super().close()
        raise OSError("device busy")


def test_close_releases_the_model_and_every_source_when_one_close_raises():
    m = OnnxForceModel(default_bundle_path())
    sources = [ListSource([]), FailsToClose([]), ListSource([])]
    rt = ForceRuntime([Sensor(f"s{k}", src, ContactGate()) for k, src in enumerate(sources)], m)
    with pytest.raises(SourceError, match=r"sensor 's1' failed to close \(OSError: device busy\)") as err:
        rt.close()
    assert isinstance(err.value, TactileForceError) and isinstance(err.value.__cause__, OSError)
    assert all(s.closed for s in sources) and m.closed and rt.closed
    rt.close()  # idempotent: nothing raised twice
