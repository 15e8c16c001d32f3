"""CameraSource on a fake capture (the V4L2 boundary) with real DIGIT frames: capture factory,
configure hook, requested size/fps/fourcc, VGA halving, dead-stream detection, reopen, and the
newest-frame grabber thread."""

import cv2
import numpy as np
import pytest
from tactile_force.edge.errors import OptionsError, SourceError
from tactile_force.edge.sources import CameraSource, StreamLost

from tests.bridge.fakes import FakeCamera, landscape


class Factory:
    """Capture factory handing out prepared fake cameras in order, recording the device asked for."""

    def __init__(self, *cams):
        self.cams, self.asked = list(cams), []

    def __call__(self, device):
        self.asked.append(device)
        return self.cams.pop(0)


def test_direct_mode_returns_every_frame_oriented_with_settings_applied(portraits):
    cam = FakeCamera([landscape(p) for p in portraits])
    seen = []

    def configure(cap):  # runs after the size/fps are set
        seen.append((cap, dict(cap.props)))
        cap.set(cv2.CAP_PROP_ZOOM, 0x123)

    with CameraSource("/dev/video4", fps=30, grab_thread=False, open_capture=Factory(cam), configure=configure) as src:
        got = [src.read() for _ in range(4)]
    assert [g.index for g in got] == [0, 1, 2, 3]
    for g, p in zip(got, portraits + portraits[:1]):
        assert g.frame.shape == (320, 240, 3) and g.frame.dtype == np.uint8 and g.frame.flags["C_CONTIGUOUS"]
        assert np.array_equal(g.frame, p) and g.meta["superseded"] == []
    assert src.stats.frames == 4 and src.stats.dropped == 0 and src.stats.corrupt == 0
    assert len(seen) == 1 and seen[0][0] is cam
    props = seen[0][1]
    assert props[cv2.CAP_PROP_FRAME_WIDTH] == 320 and props[cv2.CAP_PROP_FRAME_HEIGHT] == 240
    assert props[cv2.CAP_PROP_FPS] == 30 and props[cv2.CAP_PROP_BUFFERSIZE] == 1
    assert props[cv2.CAP_PROP_FOURCC] == cv2.VideoWriter_fourcc(*"MJPG")
    assert cam.props[cv2.CAP_PROP_ZOOM] == 0x123 and cam.released


@pytest.mark.parametrize("formats, fourcc, expected", [
    (("YUYV",), ("MJPG", "YUYV"), "YUYV"),  # MJPG refused: falls back
    (None, ("MJPG", "YUYV"), "MJPG"),
    (None, (), None),  # format left alone
])
def test_fourcc_negotiation(portraits, formats, fourcc, expected):
    cam = FakeCamera([landscape(portraits[0])], formats=formats)
    CameraSource(0, fourcc=fourcc, grab_thread=False, open_capture=Factory(cam)).close()
    assert cam.props.get(cv2.CAP_PROP_FOURCC) == (cv2.VideoWriter_fourcc(*expected) if expected else None)


def test_requested_vga_is_halved_and_other_sizes_are_corrupt(portraits):
    vga = cv2.resize(landscape(portraits[0]), (640, 480), interpolation=cv2.INTER_LINEAR)
    odd = np.zeros((100, 100, 3), np.uint8)
    cam = FakeCamera([odd, vga, landscape(portraits[1])])
    src = CameraSource(0, size=(640, 480), fps=15, grab_thread=False, open_capture=Factory(cam))
    a, b = src.read(), src.read()
    assert cam.props[cv2.CAP_PROP_FRAME_WIDTH] == 640 and cam.props[cv2.CAP_PROP_FRAME_HEIGHT] == 480
    assert a.frame.shape == b.frame.shape == (320, 240, 3)
    assert np.abs(a.frame.astype(int) - portraits[0].astype(int)).mean() < 3.0  # same image, resampled
    assert np.array_equal(b.frame, portraits[1])  # the camera fell back to QVGA: still accepted
    assert src.stats.corrupt == 1 and [a.index, b.index] == [0, 1]


def test_corrupt_frames_in_a_row_mean_a_lost_stream(portraits):
    bad = np.zeros((0, 0), np.uint8)
    good = landscape(portraits[0])
    cam = FakeCamera([bad, bad, good, bad, bad, bad, good])
    src = CameraSource(0, max_corrupt=3, grab_thread=False, open_capture=Factory(cam))
    assert src.read().index == 0  # two corrupt, then good: the count restarts
    with pytest.raises(StreamLost, match="3 corrupt frames in a row"):
        src.read()
    assert src.stats.corrupt == 5 and src.stats.frames == 1


def test_failed_grabs_then_reopen_at_a_new_node(portraits):
    frames = [landscape(p) for p in portraits]
    first, second = FakeCamera(frames, fail_after=1), FakeCamera(frames)
    factory, configured = Factory(first, second), []
    src = CameraSource("/dev/video2", max_failures=2, grab_thread=False, open_capture=factory,
                       configure=configured.append)
    assert src.read().index == 0
    with pytest.raises(StreamLost, match=r"/dev/video2: 2 grab\(s\) failed in a row"):
        src.read()
    assert src.stats.dropped == 2
    src.reopen("/dev/video5")
    assert first.released and not second.released
    assert factory.asked == ["/dev/video2", "/dev/video5"] and src.device == "/dev/video5"
    assert configured == [first, second]  # the hook runs on every open
    item = src.read()
    assert item.index == 1 and np.array_equal(item.frame, portraits[0])


def test_reopen_failure_leaves_the_source_closed(portraits):
    src = CameraSource(0, grab_thread=False,
                       open_capture=Factory(FakeCamera([landscape(portraits[0])]), FakeCamera([], opened=False)))
    with pytest.raises(SourceError, match=r"camera 0: cannot open with V4L2 .*'video' group"):
        src.reopen()
    with pytest.raises(SourceError, match="source is closed") as info:
        src.read()
    assert not isinstance(info.value, StreamLost)


def test_configure_hook_error_releases_the_capture(portraits):
    cam = FakeCamera([landscape(portraits[0])])

    def refuse(cap):
        raise SourceError("LED control refused")

    with pytest.raises(SourceError, match="LED control refused"):
        CameraSource(0, open_capture=Factory(cam), configure=refuse)
    assert cam.released


def test_bad_arguments_are_named(tmp_path):
    with pytest.raises(SourceError, match=r"camera .*video9: no such device"):
        CameraSource(str(tmp_path / "video9"))
    with pytest.raises(OptionsError, match=r"CameraSource\.max_failures=0: expected an integer >= 1"):
        CameraSource(0, max_failures=0, open_capture=Factory())


def test_grabber_thread_keeps_the_newest_frame_and_lists_superseded(portraits):
    frames = [landscape(p) for p in portraits]
    cam = FakeCamera(frames, period_s=0.002)
    src = CameraSource(0, open_capture=Factory(cam, FakeCamera(frames, period_s=0.002)))
    prev = src.read()
    skipped = 0
    for _ in range(5):
        item = src.read()
        assert item.index > prev.index
        assert [i for i, _ in item.meta["superseded"]] == list(range(prev.index + 1, item.index))
        assert all(prev.timestamp_ns < ts < item.timestamp_ns for _, ts in item.meta["superseded"])
        assert any(np.array_equal(item.frame, p) for p in portraits)
        skipped += len(item.meta["superseded"])
        prev = item
    assert src.stats.frames == 6 and src.stats.dropped >= skipped
    src.reopen()  # the thread restarts on the new capture; indices continue
    assert cam.released
    assert src.read().index > prev.index
    src.close()
    with pytest.raises(SourceError, match="source is closed"):
        src.read()


def test_grabber_thread_reports_a_dead_device(portraits):
    cam = FakeCamera([landscape(portraits[0])], fail_after=2, period_s=0.001)
    src = CameraSource("/dev/video3", max_failures=3, open_capture=Factory(cam))
    with pytest.raises(StreamLost, match=r"/dev/video3: 3 grab\(s\) failed in a row"):
        for _ in range(3):  # at most the two good frames come first
            src.read()
    assert src.stats.dropped >= 3
    src.close()
