"""GelSightMiniSource on a fake camera (the V4L2 boundary) streaming real GelSight Mini frames
(480x640, shared data): crop, orientation, corrupt frames, serial lookup, and the contact gate
still finding every labelled ball press on the source's output."""

import cv2
import numpy as np
import pytest
from tactile_force.edge import ContactGate, GateOptions
from tactile_force.edge.errors import SceneError, SourceError
from tactile_force.edge.scene import describe_scene, open_source, parse_scene
from tactile_force.edge.sources import StreamLost
from tactile_force.firmware_bridge import (
    SDK_CROP_FRACTION,
    GelSightMiniOptions,
    GelSightMiniSource,
    crop_box,
    discover,
    find_gelsight_mini,
)

from tests.conftest import shared_data

from .fakes import FakeCamera, FakeSysfsDevice, make_fake_sysfs

RED, BLUE = (0, 0, 255), (255, 0, 0)


@pytest.fixture(scope="module")
def presses():
    """(f0 no-contact, 16 presses, centres (x, y) px, radii px), all 480x640 BGR."""
    z = np.load(shared_data("gelsight_mini_ball_presses.npz"))
    return z["f0"], z["imgs"], z["touch_center"].astype(float), z["touch_radius"].astype(float)


@pytest.fixture
def tree(tmp_path):
    return make_fake_sysfs(tmp_path, [
        FakeSysfsDevice("1-5", 0x0C45, 0x636D, 0x0100, None, "GelSight Mini R0B 2BNK-CEGG", videos=[(4, 0), (5, 1)]),
        FakeSysfsDevice("1-6", 0x0C45, 0x636D, 0x0100, None, "GelSight Mini R0B 28J3-CWXU", videos=[(6, 0)]),
        FakeSysfsDevice("1-2", 0x2833, 0x0209, 0x0200, "D20001", videos=[(2, 0)]),
    ])


def _source(frames, opts=None, **cam):
    """A Mini at a /dev path discovery does not know, on a fake camera; returns (source, cameras)."""
    cams = []

    def open_capture(node):
        cams.append(FakeCamera(frames, **cam))
        return cams[-1]

    opts = opts or GelSightMiniOptions("/dev/video9", grab_thread=False)
    return GelSightMiniSource(opts, open_capture=open_capture, sys_root="/nonexistent", dev_root="/nonexistent"), cams


def _blue(img):
    b, g, r = (img[..., i].astype(int) for i in range(3))
    return (b > 200) & (g < 40) & (r < 40)


def test_real_frames_come_out_cropped_and_portrait(presses):
    f0 = presses[0]
    x0, y0, x1, y1 = crop_box(640, 480, SDK_CROP_FRACTION)
    assert (x0, y0, x1, y1) == (91, 68, 549, 412)  # floor(640/7), floor(480/7) off each side
    marked = f0.copy()
    marked[y0:y0 + 28, x0:x0 + 28] = RED  # top-left corner of what is kept
    marked[10:50, 300:340] = BLUE  # the top border, cropped away
    assert not _blue(f0).any()
    src, cams = _source([marked])
    with src:
        tf = src.read()
    out = tf.frame
    assert out.shape == (320, 240, 3) and out.dtype == np.uint8 and out.flags.c_contiguous
    assert tf.meta["sensor"] == src.name == "/dev/video9"
    # 90 degrees counter-clockwise: the kept image's top-left corner is the portrait's bottom-left.
    assert np.all(out[303:318, 2:16] == RED)
    assert not np.any(np.all(out[:150] == RED, axis=-1)) and not np.any(np.all(out[:, 120:] == RED, axis=-1))
    assert not _blue(out).any()
    cam = cams[0]
    assert (cam.props[cv2.CAP_PROP_FRAME_WIDTH], cam.props[cv2.CAP_PROP_FRAME_HEIGHT]) == (640, 480)
    assert cam.props[cv2.CAP_PROP_FPS] == 25 and cam.props[cv2.CAP_PROP_BUFFERSIZE] == 1
    assert cam.released


def test_crop_fraction_is_an_option(presses):
    marked = presses[0].copy()
    marked[10:50, 300:340] = BLUE
    src, _ = _source([marked], GelSightMiniOptions("/dev/video9", crop_fraction=0.0, grab_thread=False))
    out = src.read().frame
    src.close()
    # uncropped: landscape rows 5..25, cols 150..170 -> portrait rows 149..169, cols 5..25
    assert _blue(out[152:167, 8:22]).all()
    assert _blue(out).sum() < 2 * 20 * 20


def test_gate_finds_every_labelled_press_on_the_source_frames(presses):
    f0, imgs, centres, radii = presses
    src, _ = _source([f0, *imgs])
    frames = [src.read().frame for _ in range(1 + len(imgs))]
    src.close()
    x0, y0, x1, y1 = crop_box(640, 480, SDK_CROP_FRACTION)
    sx, sy = 320 / (x1 - x0), 240 / (y1 - y0)
    yy, xx = np.mgrid[:320, :240]
    ious = []
    for frame, (cx, cy), r in zip(frames[1:], centres, radii):
        gate = ContactGate(GateOptions.gelsight_mini())
        gate.capture_background([frames[0]])
        assert not gate.update(frames[0]).contact
        res = gate.update(frame)
        assert res.contact
        # the label circle, cropped, scaled and rotated: portrait row = 319 - x', col = y'
        row, col, rad = 319 - (cx - x0) * sx, (cy - y0) * sy, r * sx
        dist = np.hypot(res.centroid[0] - col, res.centroid[1] - row)
        assert dist < 0.5 * rad, (dist, rad)
        circle = (yy - row) ** 2 + (xx - col) ** 2 <= rad ** 2
        mask = res.mask > 0
        ious.append((mask & circle).sum() / (mask | circle).sum())
    assert min(ious) > 0.5 and np.mean(ious) > 0.6, ious


def test_corrupt_frames_are_counted_and_skipped(presses):
    f0, imgs = presses[0], presses[1]
    bad = [cv2.cvtColor(f0, cv2.COLOR_BGR2GRAY),  # one channel
           np.ascontiguousarray(f0[:240, :320]),  # another size than the camera streams
           f0.astype(np.float32),  # not uint8
           f0.reshape(-1)[:5000]]  # truncated buffer
    src, _ = _source([f0, *bad, imgs[0]])
    first, second = src.read(), src.read()
    assert (first.index, second.index) == (0, 1)
    assert src.stats.corrupt == 4 and src.stats.dropped == 0
    assert not np.array_equal(first.frame, second.frame)
    src.close()

    src, _ = _source([bad[1]])
    with pytest.raises(StreamLost, match=r"30 corrupt frames in a row .*640x480"):
        src.read()
    assert src.stats.corrupt == 30
    src.close()


def test_the_size_the_driver_settles_on_is_cropped(presses):
    small = cv2.resize(presses[1][0], (320, 240), interpolation=cv2.INTER_AREA)
    src, _ = _source([small, presses[1][0]], size=(320, 240))
    assert src.capture_size == (320, 240)
    out = src.read().frame
    assert out.shape == (320, 240, 3)
    src.read()  # the full-size frame is not what the camera streams now: corrupt, skipped
    assert src.stats.corrupt == 1
    src.close()


def test_threaded_grabbing_keeps_the_newest_frame(presses):
    src, _ = _source(list(presses[1][:4]), GelSightMiniOptions("/dev/video9"), period_s=0.002)
    with src:
        a, b = src.read(), src.read()
    assert b.index > a.index and b.frame.shape == (320, 240, 3)


def test_lookup_by_serial_and_index(tree, presses):
    result = discover(*tree)
    assert find_gelsight_mini("28J3-CWXU", result).video_node.endswith("video6")
    assert find_gelsight_mini(0, result).serial == "28J3-CWXU"  # serial order: 28J3-CWXU, 2BNK-CEGG
    with pytest.raises(SourceError, match=r"GelSight Mini 'XXXX-0000' not attached .*2BNK-CEGG"):
        find_gelsight_mini("XXXX-0000", result)
    with pytest.raises(SourceError, match="index 2: 2 GelSight Mini"):
        find_gelsight_mini(2, result)
    opened = []

    def open_capture(node):
        opened.append(node)
        return FakeCamera([presses[0]])

    opts = GelSightMiniOptions("2BNK-CEGG", grab_thread=False)
    with GelSightMiniSource(opts, open_capture=open_capture, sys_root=tree[0], dev_root=tree[1]) as src:
        assert src.read().meta["sensor"] == "2BNK-CEGG" == src.attached.serial
    assert opened[0].endswith("video4") and src.node == opened[0]
    with pytest.raises(SourceError, match="D20001|not attached"):
        GelSightMiniSource(GelSightMiniOptions("D20001"), open_capture=open_capture, sys_root=tree[0], dev_root=tree[1])
    assert len(opened) == 1


def test_a_camera_that_does_not_open_is_named(presses):
    with pytest.raises(SourceError, match="/dev/video9: cannot open"):
        _source([presses[0]], opened=False)


@pytest.mark.parametrize("opts, words", [
    (GelSightMiniOptions(crop_fraction=0.5), "crop_fraction=0.5"),
    (GelSightMiniOptions(size=(480, 640)), "landscape"),
    (GelSightMiniOptions(fps=0), "fps=0"),
])
def test_bad_options_are_named(opts, words):
    with pytest.raises(ValueError, match=words):
        opts.validate()


def test_scene_opens_a_gelsight_mini_source(tmp_path):
    data = {"sensor": [{"name": "left", "source": "gelsight_mini", "device": "ZZZZ-9999",
                        "gate": {"threshold": 28.0, "convex_hull": True}}]}
    scene = parse_scene(data, tmp_path / "scene.toml")
    assert any("GelSight Mini ZZZZ-9999" in line for line in describe_scene(scene))
    with pytest.raises(SourceError, match="GelSight Mini 'ZZZZ-9999' not attached"):
        open_source(scene.sensors[0])
    with pytest.raises(SceneError, match="gelsight_mini"):
        parse_scene({"sensor": [{"source": "gelsight"}]}, tmp_path / "scene.toml")
