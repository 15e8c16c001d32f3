"""The latency-bounded loop: sources -> gates -> [depth] -> one batched inference -> readings.

``loop`` (ForceRuntime) orders the steps of each frame, one call each: read (``grabbers``:
each sensor in its own thread), gate (``gating``), sensor watch (``sensor_watch``: a given
background holding a press, another sensor than the calibration's, the paper depth
reference), depth, one batched predict, judge (``judging``: every reading's flags and force,
with the error bar of ``bounds``). ``options`` holds what a runtime is built from (options,
sensors, the ``ForceModel`` protocol, sinks, stats), ``sharing`` who closes a model several
runtimes share, ``depth_factory`` the depth stage of depth bundles, ``replay`` a labelled
folder replayed through the runtime as ``tactile-force run`` does.
"""

from __future__ import annotations

from .depth_factory import ASSETS_DIR, build_depth_stage, depth_options_for, plan_stages, resolve_package_path
from .loop import ForceRuntime
from .options import (
    STAGES,
    ForceModel,
    ForceModelBase,
    FrameSink,
    LatencyWindow,
    ReadingSink,
    RuntimeOptions,
    RuntimeStats,
    Sensor,
    frame_sinks,
    shares_reduction,
)

__all__ = ["ASSETS_DIR", "STAGES", "ForceModel", "ForceModelBase", "ForceRuntime", "FrameSink", "LatencyWindow",
           "ReadingSink", "RuntimeOptions", "RuntimeStats", "Sensor", "build_depth_stage", "depth_options_for",
           "frame_sinks", "plan_stages", "resolve_package_path", "shares_reduction"]
