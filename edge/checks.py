"""Argument checks for the public constructors and options dataclasses, made once at
construction (never per frame).

Three helpers, so every constructor refuses a wrong argument the same way:

- :func:`expect`: one argument against a type (or a tuple of types) and optional bounds,
  ``expect(threads, int, "OnnxForceModel.threads", ge=1)``;
- :func:`check_fields`: every field of a dataclass against its annotation and the
  constraints declared on it with :func:`tactile_force.edge.typed_json.check`
  (``field(default=1, metadata=check(ge=1))``), called from ``__post_init__``;
- :func:`expect_members`: an object against a ``typing.Protocol`` (every member it
  declares is there, every method callable), ``expect_members(model, ForceModel, "ForceRuntime.model")``.

Types are read as the typed reader (:mod:`.typed_json`) reads annotations, for Python
values: ``bool`` is not an integer (a count given ``True`` is refused); numpy numbers are
numbers; a ``float`` must be finite; a ``Path`` or ``os.PathLike`` is a ``str`` or a path
object; ``list[X]`` and ``tuple[X, ...]`` take a list or a tuple; ``Callable`` anything
callable; another class an instance of it. Bounds apply to a number and to each number of
a list or tuple.

A wrong type raises :class:`~.errors.ArgumentTypeError` (a ``TypeError``), a value of the
right type out of range (or not finite) :class:`~.errors.OptionsError` (a ``ValueError``);
both name the parameter, the value and what was expected, e.g.
``GateOptions.threshold='x': expected a number, got str``.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import enum
import math
import os
import types
import typing
from pathlib import Path
from typing import Any, Literal, TypeVar, Union

import numpy as np

from .errors import ArgumentTypeError, OptionsError
from .typed_json import NO_CHECK, Check, describe_type, field_check, type_hints

T = TypeVar("T")

_INTEGERS = (int, np.integer)
_NUMBERS = (int, float, np.integer, np.floating)
_BOOLS = (bool, np.bool_)


def _shown(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _literal_ok(tp: Any, value: object) -> bool:
    for a in typing.get_args(tp):
        if isinstance(a, bool) or isinstance(value, _BOOLS):
            if isinstance(a, bool) and isinstance(value, _BOOLS) and bool(value) is a:
                return True
        elif isinstance(a, int) and isinstance(value, _INTEGERS):
            if int(value) == a:
                return True
        elif type(value) is type(a) and value == a:
            return True
    return False


def type_ok(tp: Any, value: object) -> bool:
    """True when ``value`` is of annotation ``tp`` (see the module docstring for the rules)."""
    origin = typing.get_origin(tp)
    if tp is Any or tp is object:
        return True
    if origin in (Union, types.UnionType):
        return any(type_ok(a, value) for a in typing.get_args(tp))
    if tp is None or tp is type(None):
        return value is None
    if origin is Literal:
        return _literal_ok(tp, value)
    if origin in (list, tuple, collections.abc.Sequence):
        if not isinstance(value, (list, tuple)):
            return False
        args = typing.get_args(tp)
        if origin is tuple and args and not (len(args) == 2 and args[1] is Ellipsis):
            return len(value) == len(args) and all(type_ok(a, v) for a, v in zip(args, value))
        return all(type_ok(args[0], v) for v in value) if args else True
    if origin is dict:
        return isinstance(value, dict)
    if origin is collections.abc.Callable or tp is collections.abc.Callable:
        return callable(value)
    if tp is bool:
        return isinstance(value, _BOOLS)
    if tp is int:
        return isinstance(value, _INTEGERS) and not isinstance(value, _BOOLS)
    if tp is float:
        return isinstance(value, _NUMBERS) and not isinstance(value, _BOOLS)
    if tp is Path or tp is os.PathLike:
        return isinstance(value, (str, os.PathLike))
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return isinstance(value, tp) or any(value == m.value for m in tp)
    if isinstance(tp, type) and not getattr(tp, "_is_protocol", False):
        return isinstance(value, tp)
    return True  # an annotation this checker cannot test (a protocol, a type variable)


def _numbers(value: object) -> list[float]:
    """The numbers a value holds: itself, or the numbers of a list / tuple."""
    items = value if isinstance(value, (list, tuple)) else [value]
    return [float(v) for v in items if isinstance(v, _NUMBERS) and not isinstance(v, _BOOLS)]


def _has_float(tp: Any) -> bool:
    """Whether a number in a value of annotation ``tp`` is read as a float (must be finite)."""
    origin = typing.get_origin(tp)
    if tp is float:
        return True
    if origin in (Union, types.UnionType, list, tuple, collections.abc.Sequence):
        return any(_has_float(a) for a in typing.get_args(tp) if a is not Ellipsis)
    return False


def check_value(tp: Any, value: T, name: str, chk: Check = NO_CHECK) -> T:
    """``value`` when it fits annotation ``tp`` and constraints ``chk``.

    Parameters
    ----------
    tp
        The annotation (``int``, ``float | None``, ``tuple[float, float]``, a class, ...).
    value
        The argument.
    name
        The parameter as the user wrote it, e.g. ``"GateOptions.threshold"``.
    chk
        Bounds, choices, non-empty, a predicate and the expected text
        (:class:`~.typed_json.Check`).

    Raises
    ------
    ArgumentTypeError
        ``value`` is not of type ``tp``.
    OptionsError
        ``value`` is of type ``tp`` but not finite, out of range, empty, not among the
        choices or refused by the predicate.
    """
    want = describe_type(tp, chk, None)
    if not type_ok(tp, value):
        raise ArgumentTypeError(f"{name}={_shown(value)}: expected {want}, got {type(value).__name__}")
    numbers = _numbers(value)
    if numbers and _has_float(tp) and not all(math.isfinite(v) for v in numbers):
        finite = "a finite " + want[2:] if want.startswith("a ") else f"{want} (finite)"
        raise OptionsError(f"{name}={_shown(value)}: expected {finite}")
    if not all(chk.in_range(v) for v in numbers):
        raise OptionsError(f"{name}={_shown(value)}: expected {want}")
    if chk.nonempty and isinstance(value, (str, list, tuple)) and not value:
        raise OptionsError(f"{name} is empty: expected {want}")
    if chk.choices is not None and value not in chk.choices:
        raise OptionsError(f"{name}={_shown(value)}: expected {want}")
    if chk.test is not None and not chk.test(value):
        raise OptionsError(f"{name}={_shown(value)}: expected {want}")
    return value


def expect(value: T, types_: Any, name: str, expected: str = "", *, gt: float | None = None,
           ge: float | None = None, lt: float | None = None, le: float | None = None,
           nonempty: bool = False) -> T:
    """``value`` when it is one of ``types_`` (a type, a tuple of types, or an annotation such
    as ``int | None``) within the bounds; else an error naming ``name`` (see
    :func:`check_value`). ``expected`` replaces the description made from the types and bounds.

    >>> expect(2, int, "OnnxForceModel.threads", ge=1)
    2
    """
    tp = Union[types_] if isinstance(types_, tuple) else types_  # noqa: UP007 - a runtime union of given types
    return check_value(tp, value, name, Check(gt=gt, ge=ge, lt=lt, le=le, nonempty=nonempty, expected=expected))


def protocol_members(protocol: type) -> tuple[list[str], list[str]]:
    """(attributes, methods) a ``typing.Protocol`` declares, public names only, in the order
    of its definition: annotated names and properties are attributes, functions methods."""
    attrs: list[str] = []
    methods: list[str] = []
    for cls in reversed(protocol.__mro__):
        if cls in (object, typing.Protocol, typing.Generic):
            continue
        for name in [*cls.__dict__.get("__annotations__", {}), *cls.__dict__]:
            if name.startswith("_") or name in attrs or name in methods:
                continue
            value = cls.__dict__.get(name)
            (methods if callable(value) and not isinstance(value, (property, type)) else attrs).append(name)
    return attrs, methods


def expect_members(value: T, protocol: type, name: str, expected: str = "") -> T:
    """``value`` when it has every member ``protocol`` (a ``typing.Protocol``) declares and
    each declared method is callable; else an error naming ``name`` and what is missing.

    Raises
    ------
    ArgumentTypeError
        A member is missing (or a method is not callable); the message lists them all, e.g.
        ``ForceRuntime.model=<Fake>: expected ...; Fake lacks closed, predict_reduced``.
    """
    attrs, methods = protocol_members(protocol)
    missing = [m for m in attrs if not hasattr(value, m)]
    missing += [m for m in methods if not callable(getattr(value, m, None))]
    if missing:
        want = expected or f"a {protocol.__name__} ({', '.join(attrs + methods)})"
        raise ArgumentTypeError(f"{name}={_shown(value)}: expected {want}; {type(value).__name__} lacks "
                                f"{', '.join(missing)} ({protocol.__name__} declares {', '.join(attrs + methods)})")
    return value


def check_fields(obj: object, owner: str = "") -> None:
    """Check every init field of dataclass instance ``obj`` against its annotation and its
    declared constraints (call it first in ``__post_init__``); errors name
    ``owner.field`` (``owner`` defaults to the class name).

    Raises
    ------
    ArgumentTypeError, OptionsError
        As :func:`check_value`, for the first field that does not fit.
    """
    cls = type(obj)
    hints = type_hints(cls)
    prefix = owner or cls.__name__
    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        if f.init:
            check_value(hints[f.name], getattr(obj, f.name), f"{prefix}.{f.name}", field_check(f))
