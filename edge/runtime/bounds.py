"""Every reading's error bar: the bundle's interval record
(:class:`~tactile_force.edge.bundle.interval.ForceInterval`, edge/bundle/interval.py) applied
to one reading, in O(1) and without an allocation."""

from __future__ import annotations

from ..bundle.interval import ForceInterval
from ..reading import Flags, ForceReading

_NO_CONTACT, _SATURATED = int(Flags.NO_CONTACT), int(Flags.SATURATED)


def bound(r: ForceReading, iv: ForceInterval) -> None:
    """Set the reading's ``force_low_n`` / ``force_high_n`` / ``interval`` from ``iv``.

    ``no_contact`` -> [0, the gate-closed bound]; ``saturated`` -> open above (+inf); an
    unknown bin -> NaN bounds, ``unknown``. For a reading with a force whose frame the gate
    judged against a settled background (the judging decides; edge/runtime/judging.py).

    Parameters
    ----------
    r : ForceReading
        The reading, its ``force_n`` (N) and ``flags`` set; changed in place.
    iv : ForceInterval
        The bundle's interval record that applies to its model
        (:func:`~tactile_force.edge.bundle.interval.usable_interval`).
    """
    fl = int(r.flags)  # plain int tests: IntFlag operators cost ~1 us each
    if fl & _NO_CONTACT:
        r.force_low_n, r.force_high_n, r.interval = iv.no_contact_bounds()
    else:
        r.force_low_n, r.force_high_n, r.interval = iv.bounds(r.force_n, fl & _SATURATED != 0)
