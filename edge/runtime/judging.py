"""Judging one force estimate, and a frame the gate cannot judge, for
:class:`~tactile_force.edge.runtime.loop.ForceRuntime` (docs/runtime.md, "Flags").

- :meth:`EstimateJudge.estimate`: range (``below_range`` clamped at 0 N, ``saturated`` at
  15 N), gel saturation and a contact beyond the bundle's ``data_stats`` (``saturated``, a
  lower bound), colours outside them or another sensor than the calibration's
  (``out_of_distribution``, the force kept);
- :func:`gate_verdict`: ``invalid_input`` or ``background_mismatch`` (force NaN) with a
  detail that says why and how the gate recovers.

The error bars (``force_low_n`` / ``force_high_n``) are applied where the reading is made
(``ForceRuntime._bound``, edge/bundle/interval.py).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..bundle.data_stats import DataStatsCheck
from ..reading import MAX_VALID_FORCE_N, MIN_VALID_FORCE_N, Flags

if TYPE_CHECKING:
    from ..gate.contact_gate import GateResult


class EstimateJudge:
    """Flags and honestly clamped force for the estimates of one model.

    Parameters
    ----------
    model : object
        The backend; its ``bundle.manifest.data_stats`` (when there) is what the frames are
        checked against. The check is built on first use (one warning and no check when the
        manifest has none).
    """

    __slots__ = ("_model", "_check")

    def __init__(self, model: object) -> None:
        self._model = model
        self._check: DataStatsCheck | None = None

    def stats_check(self) -> DataStatsCheck:
        """The check against the bundle's ``data_stats``, made on first use."""
        chk = self._check
        if chk is None:
            bundle = getattr(self._model, "bundle", None)
            manifest = getattr(bundle, "manifest", None)
            chk = DataStatsCheck(getattr(manifest, "data_stats", None), str(getattr(bundle, "name", "bundle")))
            self._check = chk
        return chk

    def estimate(self, raw: float, g: GateResult, error: str = "", foreign: str = "") -> tuple[Flags, float, str]:
        """Judge one estimate.

        Parameters
        ----------
        raw : float
            The model's force, N (NaN/inf: the model failed).
        g : GateResult
            The gate's decision on the frame (saturation, area fraction, deformation, thumbnail).
        error : str
            Why inference failed ("" = it did not); the detail of a non-finite ``raw``.
        foreign : str
            Why the sensor is not the one the force calibration was fitted on ("" = it is):
            adds ``out_of_distribution`` and is appended to the detail.

        Returns
        -------
        tuple of (Flags, float, str)
            The flags, the force in N (clamped to [0, 15] N; NaN when ``raw`` is not finite)
            and the detail ("" = nothing to say).
        """
        if not math.isfinite(raw):
            flags, force, detail = Flags.INVALID_INPUT, math.nan, error or f"model returned {raw}"
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
        return flags, force, detail


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
