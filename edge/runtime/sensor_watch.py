"""The health of each sensor a runtime serves, watched once per frame after its gate:

- a background given to the gate (``ContactGate.capture_background``) is checked for a press
  once, against the no-contact image the bundle carries (edge/gate/given_background.py):
  while it looks pressed, the sensor's ``no_contact`` readings carry ``background_mismatch``;
- once per new background (learnt, given or re-learnt) the sensor is compared with the one
  the force calibration was fitted on (its serial, else the calibration's no-contact
  fingerprint): another sensor's contact readings are flagged ``out_of_distribution``;
- paper depth mode: the depth stage's zero-depth reference follows the gate's background,
  also when the gate re-learns it.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

import numpy as np

from ..gate.contact_gate import GateResult
from ..gate.given_background import pressed_background, reference_thumb

if TYPE_CHECKING:
    from ..bundle.force_calibration import SensorFingerprint
    from .options import ForceModel, Sensor

_log = logging.getLogger(__name__)


class WatchReference:
    """What a runtime's sensors are compared with, from its model's bundle: the force
    calibration's sensor ``fingerprint`` (None: not calibrated, or no record) and the
    no-contact ``thumb`` (rows x cols x 3; None: the bundle carries none), ``what`` it is and
    the smallest press blob (``min_cells``, a share of the grid) a given background may hold."""

    __slots__ = ("fingerprint", "thumb", "what", "min_cells", "unchecked_said")

    def __init__(self, model: ForceModel) -> None:
        cal = model.calibration
        self.fingerprint: SensorFingerprint | None = cal.sensor if cal is not None else None
        self.thumb, self.what, self.min_cells = reference_thumb(model)
        self.unchecked_said = False  # "cannot be checked for a press" is said once per runtime


def source_serial(source: object) -> str:
    """The serial of a sensor's source when it knows one (a DIGIT source: its own, or its
    attached device's), else ""."""
    attached = getattr(source, "attached", None)
    return str(getattr(source, "serial", "") or getattr(attached, "serial", "") or "")


class SensorWatch:
    """The health of one sensor (see the module docstring).

    Parameters
    ----------
    sensor : Sensor
        The sensor watched (its gate, source and depth stage).
    reference : WatchReference
        What it is compared with (shared by the runtime's sensors).

    Attributes
    ----------
    pressed : str
        Why the background given to the sensor's gate looks pressed ("" = it does not, or it
        was not checked: no reference in the bundle).
    foreign : str
        Why the sensor is not the one the force calibration was fitted on ("" = it is).
    """

    __slots__ = ("sensor", "reference", "pressed", "foreign", "_bg_checked", "_seen", "_seen_ready",
                 "_seen_relearned", "_relearned", "_reference_frames")

    def __init__(self, sensor: Sensor, reference: WatchReference) -> None:
        self.sensor = sensor
        self.reference = reference
        self.pressed = ""
        self.foreign = ""
        self._bg_checked: np.ndarray | None = None  # the given background image checked
        self._seen = False  # the sensor check ran for (background ready, re-learnt count):
        self._seen_ready = False
        self._seen_relearned = 0
        self._relearned = sensor.gate.relearned  # paper depth mode: the re-learnt count followed
        self._reference_frames: list[np.ndarray] = []  # paper depth mode, while learning

    def observe(self, frame: np.ndarray, g: GateResult) -> None:
        """Watch one gated frame (HxWx3 uint8 BGR, checked) and its gate decision ``g``."""
        s = self.sensor
        gate = s.gate
        img = gate.background_image
        if img is not None and self._bg_checked is not img:
            self.check_background()  # once per background given to the gate
        if self.reference.fingerprint is not None and (  # once per new background: the calibration's sensor?
                not self._seen or gate.relearned != self._seen_relearned
                or gate.background_ready != self._seen_ready):
            self._check_sensor(frame, g)
        depth = s.depth
        if depth is not None and (depth.needs_reference or gate.relearned != self._relearned):
            self._depth_reference(frame, g)

    def check_background(self) -> str:
        """Check the background given to the sensor's gate for a press now, when it was not
        checked yet (the runtime also does on the first frame after one is given); returns
        :attr:`pressed`."""
        gate = self.sensor.gate
        img = gate.background_image
        if img is None or img is self._bg_checked:
            return self.pressed
        self._bg_checked = img
        origin = f"sensor {self.sensor.name}: the background given ({gate.background_origin or 'capture_background'})"
        ref = self.reference
        if ref.thumb is None:
            self.pressed = ""
            if not ref.unchecked_said:
                ref.unchecked_said = True
                _log.info("%s cannot be checked for a press: the bundle carries no no-contact image of the sensor "
                          "(calibrate-force --background, or export/quantize/compress --background, record one)",
                          origin)
            return ""
        why = pressed_background(img, ref.thumb, ref.what, origin, min_cells=ref.min_cells)
        self.pressed = why
        if why:
            _log.warning("%s; its no_contact readings are flagged background_mismatch (no force)", why)
        return why

    def _check_sensor(self, frame: np.ndarray, g: GateResult) -> None:
        """Compare the sensor with the one the force calibration was fitted on, once per new
        background (learnt, given or re-learnt), on the first no-contact frame that fits it:
        its serial when the source knows one, else the calibration's no-contact fingerprint
        (:func:`~tactile_force.edge.bundle.force_calibration.fingerprint_mismatch`). A
        mismatch flags every contact reading of the sensor ``out_of_distribution``, the
        detail naming it."""
        s = self.sensor
        fp = self.reference.fingerprint
        assert fp is not None
        ready, relearned = s.gate.background_ready, s.gate.relearned
        serial = source_serial(s.source)
        known = bool(serial and fp.serial)  # two serials decide at once
        if ready and not known and (g.contact or g.mismatch or g.invalid or self.pressed):
            return  # wait for a no-contact frame that fits a background without a press
        self._seen, self._seen_ready, self._seen_relearned = True, ready, relearned
        if not ready:
            return
        from ..bundle.force_calibration import fingerprint_mismatch

        why = fingerprint_mismatch(fp, frame, serial)
        if why and why != self.foreign:
            _log.warning("sensor %s: %s; its contact readings are flagged out_of_distribution", s.name, why)
        self.foreign = f"sensor {s.name}: {why}" if why else ""

    def _depth_reference(self, frame: np.ndarray, g: GateResult) -> None:
        """Paper depth mode: the zero-depth reference is the gate's background. The frames the
        gate learns it from are kept and handed to the depth stage once it is learnt; when the
        gate re-learns its background after a mismatch (from this frame), the reference is
        re-set from it too, so depth stays zero where the gel is untouched."""
        s = self.sensor
        depth = s.depth
        assert depth is not None
        if s.gate.relearned != self._relearned:
            self._relearned = s.gate.relearned
            if depth.options.mode == "paper":
                try:
                    depth.set_reference([frame])
                except ValueError as exc:  # unusable frame: keep the reference it had
                    _log.warning("sensor %s: paper depth reference not re-set after the gate re-learnt its "
                                 "background (%s); keeping the previous one", s.name, exc)
            return
        keep = self._reference_frames
        if not g.background_ready:
            keep.append(frame.copy())
        if s.gate.background_ready and keep:
            depth.set_reference(keep)
            keep.clear()
