"""A runtime owns its parts: each sensor's source, contact gate and depth stage (and the state
objects they work in) belong to that sensor alone, checked once when the runtime is built.

A part given to two sensors would be written by both on every frame: one gate mixes the
sensors' images (a reading of one sensor made from the other's background and buffers), one
source splits one camera's frames between two names, one depth stage mixes two references.
The runtime's workers (edge/runtime/workers.py) also run two sensors' parts at the same time,
which is safe only because no part is shared.
"""

from __future__ import annotations

import dataclasses
import enum
import types
from collections.abc import Iterator, Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..errors import OptionsError

if TYPE_CHECKING:
    from .options import Sensor

#: values that hold no sensor's state (a module: code, such as the compiled kernels every stage runs)
_PLAIN = (str, bytes, int, float, complex, bool, tuple, frozenset, type(None), enum.Enum, np.ndarray, np.generic,
          types.ModuleType)


def _state_objects(part: object) -> Iterator[tuple[str, object]]:
    """(attribute, object) of the mutable helper objects a part keeps its state in (a gate's
    background learner, a depth stage's solver): objects with attributes of their own, not
    options records (dataclasses: settings that may well be shared), arrays (possibly a
    frame handed in) or plain values."""
    names = list(getattr(part, "__dict__", {}))
    for cls in type(part).__mro__:
        names += [n for n in getattr(cls, "__slots__", ()) if n not in names]
    for name in names:
        value = getattr(part, name, None)
        if (isinstance(value, _PLAIN) or dataclasses.is_dataclass(value) or callable(value)
                or not (hasattr(value, "__dict__") or hasattr(type(value), "__slots__"))):
            continue
        yield name, value


def check_owned(sensors: Sequence[Sensor], depths: Sequence[object | None]) -> None:
    """Refuse a part shared by two sensors.

    Parameters
    ----------
    sensors
        The runtime's sensors (names unique).
    depths
        Each sensor's depth stage, in the same order (None: none), as the runtime will set it.

    Raises
    ------
    OptionsError
        Two sensors share a source, a gate, a depth stage, or a state object inside one (a
        shallow copy of a gate or a stage); the message names both sensors and the part.
    """
    owner: dict[int, tuple[str, str]] = {}  # id(part) -> (sensor, what it is to that sensor)
    held: list[object] = []  # keeps the parts alive while their ids are compared
    for s, depth in zip(sensors, depths):
        for what, part in (("source", s.source), ("gate", s.gate), ("depth stage", depth)):
            if part is None:
                continue
            kind = type(part).__name__
            found = [(f"{what} ({kind})", part)]
            if what != "source":  # a source may share a device manager or a frame pool: its own business
                found += [(f"{what}'s {name} ({type(v).__name__}, inside its {kind})", v)
                          for name, v in _state_objects(part)]
            for label, obj in found:
                first = owner.setdefault(id(obj), (s.name, label))
                held.append(obj)
                if first[0] != s.name:
                    raise OptionsError(
                        f"ForceRuntime.sensors: sensors {first[0]!r} and {s.name!r} share one {label}; expected "
                        f"each sensor to own its parts: every frame writes its sensor's {what} state, so a shared "
                        f"one mixes the sensors' images or splits one stream between two names (give each sensor "
                        f"its own {kind}: a new one, not a shallow copy)")
