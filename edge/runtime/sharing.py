"""Who closes a model that several runtimes share: a count of the open runtimes using each
model and whether one of them owned it (``ForceRuntime(owns_model=True)``). The model is
closed when the last of them closes and one of them owned it, so closing one of two runtimes
sharing a model never breaks the other."""

from __future__ import annotations

import threading
import weakref

_USERS_LOCK = threading.Lock()
#: model -> [open runtimes using it, an owning runtime has closed]; weak keys: a runtime that was
#: never closed leaves no entry behind once its model is gone (ids would be reused).
_USERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_USERS_BY_ID: dict[int, list] = {}  # models that cannot be weakly referenced (held alive by their runtimes)


def _entry(model: object, default: int) -> list:
    try:
        return _USERS.setdefault(model, [default, False])
    except TypeError:  # not weakly referenceable / not hashable
        return _USERS_BY_ID.setdefault(id(model), [default, False])


def attach(model: object) -> None:
    """One more open runtime uses ``model``."""
    with _USERS_LOCK:
        _entry(model, 0)[0] += 1


def detach(model: object, owner: bool) -> bool:
    """One runtime less uses ``model`` (``owner``: that runtime owned it); True when the model
    is to be closed now: the last runtime has closed and one of them owned it."""
    with _USERS_LOCK:
        entry = _entry(model, 1)
        entry[0] -= 1
        entry[1] = entry[1] or owner
        if entry[0] > 0:
            return False
        try:
            _USERS.pop(model, None)
        except TypeError:
            pass
        _USERS_BY_ID.pop(id(model), None)
        return bool(entry[1])
