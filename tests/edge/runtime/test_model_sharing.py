"""One model, several users: an OnnxForceModel shared by two ForceRuntimes
stepped in two threads gives every reading its own answer; who closes a model is explicit;
a closed model, and a runtime after close(), raise clear errors; RuntimeOptions are checked.

Real ONNX Runtime (the embedded default bundle), real AUROVA DIGIT frames.
"""

from __future__ import annotations

import math
import sys
import threading

import cv2
import numpy as np
import pytest
from tactile_force.edge import (
    ContactGate,
    ForceRuntime,
    OnnxForceModel,
    RuntimeOptions,
    Sensor,
    errors,
)
from tactile_force.edge.scene import default_bundle_path

from tests.conftest import ListSource, shared_data


def _frames(aurova_dir) -> tuple[np.ndarray, list[np.ndarray]]:
    bg = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")))
    paths = sorted((aurova_dir / "images").glob("*.png"), key=lambda p: int(p.stem))
    return bg, [cv2.imread(str(p)) for p in paths]


def _runtime(model, bg, frames, name: str, owns_model: bool = True) -> ForceRuntime:
    gate = ContactGate()
    gate.capture_background([bg])
    kw = {} if owns_model else {"owns_model": False}  # the default: the runtime owns what it is given
    return ForceRuntime([Sensor(name, ListSource(frames), gate)], model, RuntimeOptions(deadline_ms=1e9), **kw)


def _forces(rt: ForceRuntime) -> list[float]:
    out: list = []
    rt.run(on_reading=out.append)
    return [r.force_n for r in out]


def test_two_runtimes_in_two_threads_share_one_model_and_each_reading_is_its_own(aurova_dir):
    bg, grasp = _frames(aurova_dir)
    seq_a = grasp * 25  # the grasp forwards
    seq_b = grasp[::-1] * 25  # and backwards: the two threads feed different frames at the same time
    solo = []
    for seq in (seq_a, seq_b):  # the reference: one model per runtime, one after the other
        m = OnnxForceModel(default_bundle_path())
        solo.append(_forces(_runtime(m, bg, seq, "solo")))
    shared = OnnxForceModel(default_bundle_path())
    rts = [_runtime(shared, bg, seq_a, "left"), _runtime(shared, bg, seq_b, "right")]
    got: list[list[float]] = [[], []]
    start = threading.Barrier(2)

    def work(k: int) -> None:
        start.wait()
        got[k] = _forces(rts[k])

    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)  # interleave the two threads as often as the interpreter allows
    try:
        threads = [threading.Thread(target=work, args=(k,)) for k in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(120)
    finally:
        sys.setswitchinterval(old)
    assert [len(g) for g in got] == [len(seq_a), len(seq_b)]
    wrong = sum(1 for g, s in zip(got, solo) for a, b in zip(g, s)
                if not (math.isnan(a) and math.isnan(b)) and abs(a - b) > 0.01)
    assert wrong == 0, f"{wrong} of {2 * len(seq_a)} readings differ from one model per runtime"
    assert max(solo[0]) > 5.0  # the grasp's presses were read (not all no-contact zeros)


def test_closing_one_runtime_does_not_break_another_sharing_the_model(aurova_dir):
    bg, grasp = _frames(aurova_dir)
    shared = OnnxForceModel(default_bundle_path())
    a, b = _runtime(shared, bg, grasp, "a"), _runtime(shared, bg, grasp, "b")
    a.close()
    assert not shared.closed
    forces = _forces(b)
    assert all(math.isfinite(f) for f in forces) and max(forces) > 5.0
    b.close()
    assert shared.closed  # the last owning runtime closed it


def test_a_runtime_told_it_does_not_own_the_model_leaves_it_open(aurova_dir):
    bg, grasp = _frames(aurova_dir)
    mine = OnnxForceModel(default_bundle_path())
    rt = _runtime(mine, bg, grasp, "a", owns_model=False)
    rt.close()
    assert not mine.closed
    assert mine.predict(grasp[-1][None]).shape == (1,)
    mine.close()


def test_a_closed_model_raises_a_clear_error_and_a_runtime_refuses_it(aurova_dir):
    bg, grasp = _frames(aurova_dir)
    m = OnnxForceModel(default_bundle_path())
    m.close()
    m.close()  # idempotent
    with pytest.raises(errors.ModelClosedError, match="default.*closed"):
        m.predict(grasp[0][None])
    assert issubclass(errors.ModelClosedError, errors.TactileForceError)
    with pytest.raises(errors.ModelClosedError, match="closed model"):
        _runtime(m, bg, grasp, "s")


def test_step_after_close_raises_and_starts_no_grabber_thread(aurova_dir):
    bg, grasp = _frames(aurova_dir)
    sensors = []
    for name in ("l", "r"):
        gate = ContactGate()
        gate.capture_background([bg])
        sensors.append(Sensor(name, ListSource(grasp), gate))
    rt = ForceRuntime(sensors, OnnxForceModel(default_bundle_path()), RuntimeOptions(deadline_ms=1e9))
    assert rt.step()
    rt.close()
    assert all(s.source.closed for s in sensors)
    before = {t.name for t in threading.enumerate()}
    for call in (rt.step, rt.start, rt.run):
        with pytest.raises(errors.ModelClosedError, match="closed"):
            call()
    assert not [t for t in threading.enumerate() if t.name.startswith("read-") and t.name not in before]
    rt.close()  # idempotent


@pytest.mark.parametrize("field,value", [("deadline_ms", math.nan), ("deadline_ms", 0.0), ("deadline_ms", -1.0),
                                         ("deadline_ms", math.inf), ("threads", 0), ("latency_window", 0)])
def test_runtime_options_are_validated_naming_the_field(field, value):
    with pytest.raises(errors.OptionsError, match=f"RuntimeOptions.{field}="):
        RuntimeOptions(**{field: value})
