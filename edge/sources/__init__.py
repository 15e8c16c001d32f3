"""Frame sources: a DIGIT camera (OpenCV V4L2, ``camera``), a replay folder or a video file
(``files``), and the no-contact background images a gate starts from (``background``)."""

from __future__ import annotations

from .background import load_background
from .camera import CameraSource, Capture, missing_camera, open_v4l2
from .common import MAX_CORRUPT_IN_ROW, Clock, StreamLost, orient_digit
from .files import ReplayFolderSource, VideoFileSource

__all__ = ["MAX_CORRUPT_IN_ROW", "CameraSource", "Capture", "Clock", "ReplayFolderSource", "StreamLost",
           "VideoFileSource", "load_background", "missing_camera", "open_v4l2", "orient_digit"]
