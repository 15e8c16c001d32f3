"""Every reading of a :class:`~tactile_force.edge.runtime.loop.ForceRuntime` frame, made and
judged in this one place (docs/runtime.md, "Flags"):

- :meth:`Judge.estimate`: one model estimate: range (``below_range`` clamped at 0 N,
  ``saturated`` at 15 N), gel saturation and a contact beyond the bundle's ``data_stats``
  (``saturated``, a lower bound), colours outside them or another sensor than the
  calibration's (``out_of_distribution``, the force kept);
- :meth:`Judge.gated`: a frame the model does not read: the gate's verdict (``invalid_input``
  or ``background_mismatch``, force NaN, see :func:`gate_verdict`) or ``no_contact`` (0 N;
  with ``background_mismatch`` and no force while the given background looks pressed);
- :meth:`Judge.invalid`: a frame refused before or after the gate (frame contract, exposure,
  a failed depth stage): ``invalid_input``, force NaN.

A reading with a force whose frame the gate judged against a settled background gets its
error bar (``force_low_n`` / ``force_high_n``) from the bundle's interval
(:func:`~tactile_force.edge.runtime.bounds.bound`). The ``late`` flag is the loop's, set when
the reading is finished.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..bundle.data_stats import DataStatsCheck
from ..bundle.interval import ForceInterval, usable_interval
from ..reading import MAX_VALID_FORCE_N, MIN_VALID_FORCE_N, Flags, ForceReading, StageLatency
from .bounds import bound

if TYPE_CHECKING:
    from ..bundle.store import Bundle
    from ..frames import TimedFrame
    from ..gate.contact_gate import ContactGate, GateResult

_NAN = math.nan


class Judge:
    """The readings of one runtime's frames: flags, honestly clamped force, detail, error bar.

    Parameters
    ----------
    bundle : Bundle or None
        The model's bundle: its ``manifest.data_stats`` (when there) is what the frames are
        checked against (the check is built on first use: one warning and no check when the
        manifest has none); its ``manifest.interval`` gives every reading's error bar when it
        was fitted for this model (:func:`~tactile_force.edge.bundle.interval.usable_interval`).
        None: no check, every interval ``unknown``.
    """

    __slots__ = ("_bundle", "_check", "interval")

    def __init__(self, bundle: Bundle | None) -> None:
        self._bundle = bundle
        self._check: DataStatsCheck | None = None
        #: the interval record applied to every reading (None: every interval is ``unknown``)
        self.interval: ForceInterval | None = usable_interval(bundle)

    def stats_check(self) -> DataStatsCheck:
        """The check against the bundle's ``data_stats``, made on first use."""
        chk = self._check
        if chk is None:
            bundle = self._bundle
            if bundle is None:
                chk = DataStatsCheck(None, "bundle")
            else:
                chk = DataStatsCheck(bundle.manifest.data_stats, str(bundle.name))
            self._check = chk
        return chk

    def estimate(self, sensor: str, tf: TimedFrame, raw: float, g: GateResult, latency: StageLatency,
                 error: str = "", foreign: str = "") -> ForceReading:
        """The reading of one model estimate.

        Parameters
        ----------
        sensor : str
            The sensor's name.
        tf : TimedFrame
            The frame (time stamp, index, truth).
        raw : float
            The model's force, N (NaN/inf: the model failed).
        g : GateResult
            The gate's decision on the frame (saturation, area, deformation, thumbnail).
        latency : StageLatency
            The reading's stage times so far (ms).
        error : str
            Why inference failed ("" = it did not); the detail of a non-finite ``raw``.
        foreign : str
            Why the sensor is not the one the force calibration was fitted on ("" = it is):
            adds ``out_of_distribution`` and is appended to the detail.

        Returns
        -------
        ForceReading
            Its force in N clamped to [0, 15] N (NaN when ``raw`` is not finite), its flags,
            detail ("" = nothing to say) and error bar.
        """
        if not math.isfinite(raw):
            flags, force, detail = Flags.INVALID_INPUT, _NAN, error or f"model returned {raw}"
        else:
            flags, force = Flags.NONE, raw
            if raw < MIN_VALID_FORCE_N:
                flags |= Flags.BELOW_RANGE
                force = max(raw, 0.0)
            if raw >= MAX_VALID_FORCE_N:
                flags |= Flags.SATURATED
                force = MAX_VALID_FORCE_N
            detail = ""
            if g.saturation_seen:
                flags |= Flags.SATURATED
                detail = "gel saturation seen in the frame"
            chk = self._check if self._check is not None else self.stats_check()
            if chk.active:
                beyond = chk.beyond_coverage(g.area_frac, g.deformation)
                if beyond:
                    flags |= Flags.SATURATED
                    detail = beyond
                ood = chk.out_of_distribution(g.thumb)
                if ood:
                    flags |= Flags.OUT_OF_DISTRIBUTION
                    detail = f"{detail}; {ood}" if detail else ood
        if foreign:  # another sensor than the calibration's
            flags |= Flags.OUT_OF_DISTRIBUTION
            detail = f"{detail}; {foreign}" if detail else foreign
        r = ForceReading(sensor, tf.timestamp_ns, tf.index, force, flags, latency, raw, g.area_px, tf.truth_n, detail)
        iv = self.interval
        if iv is not None and force == force and g.background_ready:  # judged against a settled background
            bound(r, iv)
        return r

    def gated(self, sensor: str, tf: TimedFrame, g: GateResult, latency: StageLatency, pressed: str,
              gate: ContactGate) -> ForceReading:
        """The reading of a frame the gate stopped: it cannot judge it (``g.mismatch`` or
        ``g.invalid``: :func:`gate_verdict`, force NaN), or it saw no contact (0 N,
        ``no_contact``; while the gate learns its background the detail says so and the
        interval stays ``unknown``). ``pressed``: why the sensor's given background looks
        pressed ("" = it does not): then "no contact" is not known, ``no_contact`` with
        ``background_mismatch`` and no force. ``gate``: the sensor's gate (its
        ``relearn_frames``, named in a mismatch's detail)."""
        if g.mismatch or g.invalid:
            flags, detail = gate_verdict(sensor, tf.index, g, gate.options.relearn_frames)
            return ForceReading(sensor, tf.timestamp_ns, tf.index, _NAN, flags, latency, _NAN, g.area_px, tf.truth_n,
                                detail)
        if pressed:
            return ForceReading(sensor, tf.timestamp_ns, tf.index, _NAN, Flags.NO_CONTACT | Flags.BACKGROUND_MISMATCH,
                                latency, _NAN, g.area_px, tf.truth_n, pressed)
        ready = g.background_ready
        r = ForceReading(sensor, tf.timestamp_ns, tf.index, 0.0, Flags.NO_CONTACT, latency, _NAN, g.area_px,
                         tf.truth_n, "" if ready else "learning background")
        iv = self.interval
        if iv is not None and ready:
            bound(r, iv)
        return r

    def invalid(self, sensor: str, tf: TimedFrame, latency: StageLatency, detail: str, area: int = 0) -> ForceReading:
        """The ``invalid_input`` reading (force NaN) of a frame refused for ``detail``;
        ``area``: the contact area the gate found (px), 0 when it did not gate it."""
        return ForceReading(sensor, tf.timestamp_ns, tf.index, _NAN, Flags.INVALID_INPUT, latency, _NAN, area,
                            tf.truth_n, detail)


def gate_verdict(sensor: str, frame_index: int, g: GateResult, relearn_frames: int) -> tuple[Flags, str]:
    """The flag and detail for a frame the gate cannot judge (force NaN, the CNN not run).

    Parameters
    ----------
    sensor : str
        The sensor's name.
    frame_index : int
        The frame's index (named in an ``invalid_input`` detail).
    g : GateResult
        The gate's decision; ``g.invalid`` or ``g.mismatch`` is set.
    relearn_frames : int
        The gate's ``GateOptions.relearn_frames`` (0: it re-learns only when told).

    Returns
    -------
    tuple of (Flags, str)
        ``invalid_input`` (RGB order, uniform, noise burst, blur) or ``background_mismatch``,
        and the detail saying why (and, for a mismatch, how the gate recovers).
    """
    if g.invalid:
        return Flags.INVALID_INPUT, f"{sensor} frame {frame_index}: {g.invalid}"
    recover = (f"background re-learnt after {relearn_frames} stable frames without a contact-like blob, or as soon "
               "as a frame fits again" if relearn_frames else "call ContactGate.relearn() with the gripper open")
    return Flags.BACKGROUND_MISMATCH, f"{sensor}: background mismatch: {g.mismatch} ({recover})"
