"""Frame sources: a DIGIT camera (OpenCV V4L2), a replay folder, a video file, and the
no-contact background images a gate starts from."""

from __future__ import annotations

from .files import (
    MAX_CORRUPT_IN_ROW,
    CameraSource,
    Capture,
    Clock,
    ReplayFolderSource,
    StreamLost,
    VideoFileSource,
    load_background,
    missing_camera,
    open_v4l2,
    orient_digit,
)

__all__ = ["MAX_CORRUPT_IN_ROW", "CameraSource", "Capture", "Clock", "ReplayFolderSource", "StreamLost",
           "VideoFileSource", "load_background", "missing_camera", "open_v4l2", "orient_digit"]
