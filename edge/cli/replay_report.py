"""What ``run`` and ``demo`` tell about a replay with truth: RE and MAE lines, and force and
truth against time drawn beside the first reading file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..data.metrics import readings_error
from ..reading import ForceReading

#: File name of the demo's force-over-time plot (README and docs name it too).
PLOT_NAME = "force_vs_time.png"


def truth_lines(readings: list[ForceReading]) -> list[str]:
    """RE and MAE (mean +- std) over the CNN readings with truth, overall and per 1 N bin,
    and how many frames with truth >= 1 N got no CNN reading; [] when no frame had truth."""
    rep, n_truth, missed = readings_error(readings)
    if not n_truth:
        return []
    lines = []
    if rep is not None:
        o = rep.overall
        lines.append(f"error vs truth over {o.n} CNN readings: RE {o.re_mean:.3f} +- {o.re_std:.3f}, "
                     f"MAE {o.mae_mean:.3f} +- {o.mae_std:.3f} N")
        for label, st in rep.per_bin.items():
            lines.append(f"  {label + ' N':>8}: RE {st.re_mean:.3f} +- {st.re_std:.3f}, "
                         f"MAE {st.mae_mean:.3f} +- {st.mae_std:.3f} N  (n={st.n})")
    else:
        lines.append(f"error vs truth: no CNN reading among the {n_truth} frames with truth")
    if missed:
        lines.append(f"{missed} frame(s) with truth >= 1 N got no force estimate (no_contact or invalid_input)")
    return lines


def replay_plot_path(outs: list[str], scene) -> Path | None:
    """Where ``run`` draws a labelled replay's force and truth against time: next to the first
    reading output, ``<its name>_force_vs_time.png`` (None when the run writes no file)."""
    paths = [Path(o) for o in outs] or [Path(p) for o in getattr(scene, "outputs", [])
                                         if (p := getattr(o, "path", None))]
    if not paths:
        return None
    first = paths[0]
    return first.with_name(f"{first.stem}_{PLOT_NAME}")


#: the x axis of a replay read as fast as it is processed: its stamps are processing times, not the sensor's
INDEX_AXIS = "frame of the recording (read unpaced: no --fps)"


def plot_force(readings: list[ForceReading], path: Path, by_index: bool = False) -> str:
    """Force against time, truth vs estimate, as PNG (:func:`tactile_force.edge.report.plots.force_vs_time`);
    ``by_index``: against each reading's frame index instead (a replay read unpaced, whose stamps only
    say when each frame was processed)."""
    if by_index:
        t = np.array([r.frame_index for r in readings], np.float64)
    else:
        t = np.array([r.timestamp_ns for r in readings], np.float64)
        t = (t - t[0]) / 1e9 if t.size else t
    est = np.array([r.force_n for r in readings], np.float64)
    truth = np.array([np.nan if r.truth_n is None else r.truth_n for r in readings], np.float64)
    return _plot_cv(t, est, truth, path, INDEX_AXIS if by_index else "time (s)")


def _plot_cv(t: np.ndarray, est: np.ndarray, truth: np.ndarray, path: Path, xlabel: str = "time (s)") -> str:
    """The force plot (OpenCV, the package's one plotting module); returns how it was drawn."""
    from ..report.plots import force_vs_time

    force_vs_time(t, est, truth, path, xlabel=xlabel)
    return "opencv"
