"""The latency-bounded loop: sources -> gates -> [depth] -> one batched inference -> readings.

``loop`` (ForceRuntime) orders the steps; ``grabbers`` reads each sensor in its own thread;
``judging`` turns one estimate or one gate verdict into a reading's flags.
"""

from __future__ import annotations

from .loop import (
    ASSETS_DIR,
    STAGES,
    ForceModel,
    ForceRuntime,
    FrameSink,
    LatencyWindow,
    ReadingSink,
    RuntimeOptions,
    RuntimeStats,
    Sensor,
    build_depth_stage,
    depth_options_for,
    frame_sinks,
    plan_stages,
    resolve_package_path,
    shares_reduction,
)

__all__ = ["ASSETS_DIR", "STAGES", "ForceModel", "ForceRuntime", "FrameSink", "LatencyWindow", "ReadingSink",
           "RuntimeOptions", "RuntimeStats", "Sensor", "build_depth_stage", "depth_options_for", "frame_sinks",
           "plan_stages", "resolve_package_path", "shares_reduction"]
