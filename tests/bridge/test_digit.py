"""DigitSource on a fake camera (the V4L2 boundary) with real DIGIT frames."""

import cv2
import numpy as np
import pytest
from tactile_force.edge.errors import SourceError
from tactile_force.firmware_bridge import DigitOptions, DigitSource, intensity_code, reset_usb_device
from tactile_force.firmware_bridge.sysfs import UsbDeviceInfo

from .fakes import FakeCamera, FakeSysfsDevice, FakeUsbDevice, fake_find, landscape, make_fake_sysfs


@pytest.fixture
def tree(tmp_path):
    return make_fake_sysfs(tmp_path, [
        FakeSysfsDevice("1-2", 0x2833, 0x0209, 0x0200, "D20001", videos=[(2, 0), (3, 1)]),
        FakeSysfsDevice("1-3", 0x2833, 0x0209, 0x0150, "D00150", videos=[(0, 0)]),
    ])


class Cameras:
    """Opens fake cameras per node; ``script`` gives the next camera's fail_after/opened."""

    def __init__(self, frames, script):
        self.frames, self.script, self.opened = frames, list(script), []

    def __call__(self, node):
        fail_after, ok = self.script.pop(0) if self.script else (None, True)
        cam = FakeCamera(self.frames, fail_after=fail_after, opened=ok)
        self.opened.append((node, cam))
        return cam


def test_frames_are_oriented_like_digit_interface(tree, portraits):
    cams = Cameras([landscape(p) for p in portraits], [])
    with DigitSource(DigitOptions("D20001", intensity=(15, 8, 1)), open_capture=cams, sys_root=tree[0],
                     dev_root=tree[1]) as src:
        frames = [src.read() for _ in range(3)]
        assert src.name == "D20001"
    node, cam = cams.opened[0]
    assert node.endswith("video2")
    for tf, p in zip(frames, portraits):
        assert tf.frame.shape == (320, 240, 3) and tf.frame.dtype == np.uint8
        assert np.array_equal(tf.frame, p)
    assert [tf.index for tf in frames] == [0, 1, 2]
    assert frames[0].timestamp_ns < frames[2].timestamp_ns
    assert cam.props[cv2.CAP_PROP_FRAME_WIDTH] == 320 and cam.props[cv2.CAP_PROP_FPS] == 60
    assert cam.props[cv2.CAP_PROP_ZOOM] == (15 << 8) | (8 << 4) | 1 == intensity_code(15, 8, 1)
    assert cam.released


def test_vga_is_halved_to_the_frame_contract(tree, portraits):
    big = cv2.resize(landscape(portraits[0]), (640, 480), interpolation=cv2.INTER_LINEAR)
    cams = Cameras([big], [])
    src = DigitSource(DigitOptions(0, resolution="VGA", fps=15), open_capture=cams, sys_root=tree[0], dev_root=tree[1])
    f = src.read().frame
    assert f.shape == (320, 240, 3)
    assert np.abs(f.astype(int) - portraits[0].astype(int)).mean() < 3.0  # same image, resampled
    assert cams.opened[0][1].props[cv2.CAP_PROP_FRAME_HEIGHT] == 480


def test_old_firmware_refuses_rgb_intensity(tree, portraits):
    cams = Cameras([landscape(portraits[0])], [])
    with pytest.raises(SourceError, match=r"revision 150 .*needs >= 200"):
        DigitSource(DigitOptions("D00150", intensity=(1, 1, 1)), open_capture=cams, sys_root=tree[0], dev_root=tree[1])
    assert cams.opened == []  # refused before the camera is touched


@pytest.mark.parametrize("opts, words", [
    (DigitOptions(resolution="HD"), "resolution 'HD'"),
    (DigitOptions(fps=60, resolution="VGA"), "fps 60 at VGA"),
    (DigitOptions(intensity=(16, 0, 0)), "0..15"),
])
def test_bad_options_are_named(opts, words):
    with pytest.raises(ValueError, match=words):
        opts.validate()


def test_reconnects_with_backoff_after_read_failures(tree, portraits):
    # first camera dies after 2 frames; two reopen attempts fail; the third works
    cams = Cameras([landscape(p) for p in portraits], [(2, True), (None, False), (None, False), (None, True)])
    sleeps = []
    src = DigitSource(DigitOptions("D20001", backoff_s=0.1, backoff_max_s=0.3, usb_reset=False),
                      open_capture=cams, sys_root=tree[0], dev_root=tree[1], sleep=sleeps.append)
    got = [src.read() for _ in range(4)]
    assert [np.array_equal(g.frame, portraits[i % 3]) for i, g in enumerate(got[:2])] == [True, True]
    assert sleeps == [0.1, 0.2, 0.3]  # doubled, capped
    assert src.reconnects == 3 and src.stats.dropped == 1 and src.stats.frames == 4
    assert [i for i in (g.index for g in got)] == [0, 1, 2, 3]


def test_gives_up_with_a_clear_error(tree, portraits):
    cams = Cameras([landscape(portraits[0])], [(0, True)] + [(None, False)] * 3)
    src = DigitSource(DigitOptions("D20001", reconnect_attempts=3, backoff_s=0.0, usb_reset=False),
                      open_capture=cams, sys_root=tree[0], dev_root=tree[1], sleep=lambda s: None)
    with pytest.raises(SourceError, match=r"D20001: stream lost .* 3 reconnect attempts failed.*cannot open"):
        src.read()


def test_usb_reset_targets_bus_and_address():
    devs = [FakeUsbDevice(0x2833, 0x0209, bus=1, address=4), FakeUsbDevice(0x2833, 0x0209, bus=1, address=5)]
    reset_usb_device(UsbDeviceInfo(0x2833, 0x0209, 0x200, "D1", bus=1, address=5), find=fake_find(devs))
    assert [d.resets for d in devs] == [0, 1]
    with pytest.raises(SourceError, match="no device at bus 002"):
        reset_usb_device(UsbDeviceInfo(0x2833, 0x0209, 0x200, "D1", bus=2, address=5), find=fake_find(devs))


def test_endless_corrupt_frames_count_as_a_dead_stream(tree, portraits):
    empty = np.zeros((0, 0), np.uint8)
    cams = Cameras([empty], [(None, True), (None, True)])
    cams.frames_by_call = None
    src = DigitSource(DigitOptions("D20001", reconnect_attempts=1, backoff_s=0.0, usb_reset=False),
                      open_capture=cams, sys_root=tree[0], dev_root=tree[1], sleep=lambda s: None)
    with pytest.raises(SourceError, match="corrupt frames"):
        src.read()
    assert src.stats.corrupt > 0 and src.reconnects == 1


def test_reconnect_follows_a_replug_to_a_new_node_and_restores_the_leds(tree, portraits):
    sys_root, dev_root = tree

    def replug(seconds):  # during the backoff the kernel re-enumerates the DIGIT as video6
        for folder in (sys_root / "class" / "video4linux", dev_root):
            (folder / "video2").rename(folder / "video6")

    cams = Cameras([landscape(p) for p in portraits], [(1, True), (None, True)])
    src = DigitSource(DigitOptions("D20001", intensity=(3, 2, 1), usb_reset=False), open_capture=cams,
                      sys_root=sys_root, dev_root=dev_root, sleep=replug)
    assert src.attached.serial == "D20001" and src.node.endswith("video2")
    first, second = src.read(), src.read()
    assert [node.rsplit("/", 1)[1] for node, _ in cams.opened] == ["video2", "video6"]
    assert src.node.endswith("video6") and src.reconnects == 1
    assert cams.opened[0][1].released and not cams.opened[1][1].released
    assert cams.opened[1][1].props[cv2.CAP_PROP_ZOOM] == intensity_code(3, 2, 1)  # LEDs set again after reopen
    assert (first.index, second.index) == (0, 1) and second.meta["sensor"] == "D20001"
    assert np.array_equal(second.frame, portraits[0])  # the new camera's first frame
    src.close()
    with pytest.raises(SourceError, match="source is closed"):
        src.read()
