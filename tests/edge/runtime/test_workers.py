"""The workers of a runtime with several sensors (edge/runtime/workers.py): how many the auto
rule picks, every item worked exactly once whichever thread takes it, an item's exception
raised in the caller's thread, threads ended by stop(), or when their runtime (grabbers too)
or virtual DIGIT is dropped without close(); ``RuntimeOptions.workers`` checked where it
enters. Real threads; no timing assertions."""

from __future__ import annotations

import gc
import threading

import numpy as np
import pytest
from tactile_force.edge import ContactGate, ForceRuntime, OnnxForceModel, RuntimeOptions, Sensor
from tactile_force.edge.errors import ArgumentTypeError, OptionsError
from tactile_force.edge.runtime.workers import Workers, worker_count
from tactile_force.edge.scene import default_bundle_path

from tests.conftest import FakeClock, ListSource


def test_auto_picks_two_only_for_several_sensors_on_two_cores_with_the_real_clock():
    assert worker_count(None, 8, True, cores=2) == 2
    assert worker_count(None, 8, True, cores=16) == 2
    assert worker_count(None, 1, True, cores=16) == 1  # one sensor: today's single thread
    assert worker_count(None, 8, True, cores=1) == 1
    assert worker_count(None, 8, False, cores=2) == 1  # an injected clock: one order of clock reads
    assert worker_count(4, 3, False, cores=1) == 3  # asked: at most one per sensor
    assert worker_count(1, 8, True, cores=2) == 1


@pytest.mark.parametrize("bad, error", [(0, OptionsError), (17, OptionsError), (2.0, ArgumentTypeError),
                                        (True, ArgumentTypeError), ("2", ArgumentTypeError)])
def test_runtime_options_workers_is_checked_where_it_enters(bad, error):
    with pytest.raises(error, match=r"RuntimeOptions\.workers="):
        RuntimeOptions(workers=bad)


def test_every_item_is_worked_once_and_on_two_threads():
    w = Workers(2, "t")
    meet = threading.Barrier(2, timeout=20.0)  # the first two items only pass together
    seen: dict[int, str] = {}

    def work(i: int) -> None:
        if i < 2:
            meet.wait()
        seen[i] = threading.current_thread().name

    for _ in range(3):  # the helper thread is reused step after step
        seen.clear()
        w.run(work, list(range(8)))
        assert sorted(seen) == list(range(8))
        assert {seen[0], seen[1]} == {threading.current_thread().name, "work-t-1"}
    w.stop()
    assert not [t for t in threading.enumerate() if t.name == "work-t-1"]
    w.run(work, [5, 6])  # after stop: in the caller's thread, no error
    assert seen[5] == seen[6] == threading.current_thread().name


def test_an_item_that_raises_raises_in_the_callers_thread_after_every_item():
    w = Workers(2, "e")
    done: list[int] = []

    def work(i: int) -> None:
        if i == 3:
            raise KeyError("item 3")
        done.append(i)

    with pytest.raises(KeyError, match="item 3"):
        w.run(work, list(range(6)))
    assert sorted(done) == [0, 1, 2, 4, 5]
    w.stop()


def test_one_sensor_keeps_the_single_thread_path_and_an_injected_clock_runs_one_thread():
    model = OnnxForceModel(default_bundle_path())
    one = ForceRuntime([Sensor("a", ListSource([]), ContactGate())], model, RuntimeOptions(workers=2),
                       owns_model=False)
    assert one.workers == 1 and one._workers is None
    one.close()
    sensors = [Sensor(f"s{k}", ListSource([]), ContactGate()) for k in range(3)]
    fake = ForceRuntime(sensors, model, clock=FakeClock(1000), owns_model=False)
    assert fake.workers == 1
    fake.close()
    many = ForceRuntime([Sensor(f"g{k}", ListSource([]), ContactGate()) for k in range(2)], model,
                        RuntimeOptions(workers=2), owns_model=False)
    helper = many._workers
    assert helper is not None
    helper.run(lambda _: None, [0, 1])  # its worker thread has started
    assert [t for t in threading.enumerate() if t.name == "work-g0-g1-1"]
    del many  # dropped without close(): its worker ends with it
    gc.collect()
    for t in [t for t in threading.enumerate() if t.name == "work-g0-g1-1"]:
        t.join(20.0)
    assert not [t for t in threading.enumerate() if t.name == "work-g0-g1-1"]
    model.close()


def _ended(name: str) -> bool:
    """Whether every thread called ``name`` has ended (each joined for up to 20 s)."""
    for t in [t for t in threading.enumerate() if t.name == name]:
        t.join(20.0)
    return not [t for t in threading.enumerate() if t.name == name]


def test_a_runtime_dropped_without_close_leaves_no_grabber_behind():
    model = OnnxForceModel(default_bundle_path())
    frames = [np.zeros((320, 240, 3), np.uint8)] * 3
    rt = ForceRuntime([Sensor(f"drop-{k}", ListSource(frames), ContactGate()) for k in "ab"], model,
                      owns_model=False)
    assert rt.start(wait_s=20.0)  # each grabber has handed over a frame and waits for room for the next
    assert {"read-drop-a", "read-drop-b"} <= {t.name for t in threading.enumerate()}
    del rt
    gc.collect()
    assert _ended("read-drop-a") and _ended("read-drop-b")
    model.close()


def test_a_virtual_digit_dropped_without_close_leaves_no_render_thread_behind():
    from tactile_force.edge.synthetic import VirtualDigitSource

    src = VirtualDigitSource(seed=3, n_grasps=1, name="dropped-digit", render_ahead=2)
    assert src.read() is not None  # the render thread runs, its queue full, waiting for room
    assert [t for t in threading.enumerate() if t.name == "render-dropped-digit"]
    del src
    gc.collect()
    assert _ended("render-dropped-digit")
