"""A video whose frames cannot fit the frame contract is refused when it is opened, not
replayed as 0 readings (9ed225d: a VGA video gave 0 readings and exit 0)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from tactile_force.edge.errors import SourceError
from tactile_force.edge.sources import VideoFileSource


def _video(path, w, h, n=3):
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (w, h))
    assert vw.isOpened()
    for i in range(n):
        vw.write(np.full((h, w, 3), 60 + 20 * i, np.uint8))
    vw.release()
    return path


def test_vga_video_is_refused_naming_its_size(tmp_path):
    with pytest.raises(SourceError, match=r"vga\.avi: frames are 640x480 pixels; expected 240x320"):
        VideoFileSource(_video(tmp_path / "vga.avi", 640, 480))


@pytest.mark.parametrize("w, h", [(240, 320), (320, 240)])
def test_digit_sized_videos_play(tmp_path, w, h):
    src = VideoFileSource(_video(tmp_path / "digit.avi", w, h))
    frames = [tf.frame for tf in src]
    assert len(frames) == 3 and all(f.shape == (320, 240, 3) for f in frames)
