"""Typed JSON: dataclasses to and from plain JSON values, validated by their annotations.

One reader serves every typed record the package stores as JSON (the bundle manifest and
its sections): each field is checked against its type annotation, and an error names the
dotted path of the field, e.g. ``model.json: error.vs_truth.re_mean: expected a number,
got 'abc'``. Supported annotations: ``str``, ``int``, ``float`` (finite; write ``None``
for "not measured"), ``bool``, ``str``-valued :class:`enum.Enum` subclasses, ``list[X]``,
``dict[str, X]``, unions such as ``X | None`` or ``str | float``, and nested dataclasses.

A dataclass may define ``check(self) -> None`` raising ``ValueError`` for rules that span
fields; the message is prefixed with the dataclass's path.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import types
import typing
from typing import Any, TypeVar, Union

T = TypeVar("T")


class TypedJsonError(ValueError):
    """A JSON value does not fit the typed record; ``str()`` names the field path."""


def _describe(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _convert(tp: Any, value: object, path: str) -> Any:
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        options = typing.get_args(tp)
        if value is None:
            if type(None) in options:
                return None
            raise TypedJsonError(f"{path}: is null; expected {_type_name(tp)}")
        errors = []
        for option in options:
            if option is type(None):
                continue
            try:
                return _convert(option, value, path)
            except TypedJsonError as exc:
                errors.append(exc)
        if len(errors) == 1:
            raise errors[0]
        raise TypedJsonError(f"{path}: expected {_type_name(tp)}, got {_describe(value)}")
    if origin is list:
        (item,) = typing.get_args(tp)
        if not isinstance(value, list):
            raise TypedJsonError(f"{path}: expected a list, got {_describe(value)}")
        return [_convert(item, v, f"{path}[{i}]") for i, v in enumerate(value)]
    if origin is dict:
        _, item = typing.get_args(tp)
        if not isinstance(value, dict):
            raise TypedJsonError(f"{path}: expected an object, got {_describe(value)}")
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise TypedJsonError(f"{path}: key {_describe(k)} is not a string")
            out[k] = _convert(item, v, f"{path}.{k}")
        return out
    if tp is Any:
        return value
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return from_json(tp, value, path)
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        try:
            return tp(value)
        except ValueError:
            allowed = ", ".join(repr(m.value) for m in tp)
            raise TypedJsonError(f"{path}: {_describe(value)} is not one of {allowed}") from None
    if tp is bool:
        if not isinstance(value, bool):
            raise TypedJsonError(f"{path}: expected true or false, got {_describe(value)}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypedJsonError(f"{path}: expected an integer, got {_describe(value)}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TypedJsonError(f"{path}: expected a number, got {_describe(value)}")
        if not math.isfinite(value):
            raise TypedJsonError(f"{path}: expected a finite number, got {value}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise TypedJsonError(f"{path}: expected a string, got {_describe(value)}")
        return value
    raise TypeError(f"{path}: typed_json does not support the annotation {tp!r}")  # a bug in a record class


def _type_name(tp: Any) -> str:
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        return " or ".join(_type_name(a) for a in typing.get_args(tp))
    if origin is list:
        return f"a list of {_type_name(typing.get_args(tp)[0])}"
    if origin is dict:
        return "an object"
    if tp is type(None):
        return "null"
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return "an object"
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return "one of " + ", ".join(repr(m.value) for m in tp)
    return {bool: "true or false", int: "an integer", float: "a number", str: "a string"}.get(tp, repr(tp))


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def from_json(cls: type[T], raw: object, path: str = "") -> T:
    """Build dataclass ``cls`` from a JSON object, checking every field's type.

    Parameters
    ----------
    cls
        A dataclass whose field annotations are among the supported kinds.
    raw
        The parsed JSON value (a dict for a dataclass).
    path
        Where ``raw`` came from, prefixed to every error (e.g. ``"model.json: "``-style
        file name, then the dotted field path is appended).

    Returns
    -------
    An instance of ``cls``.

    Raises
    ------
    TypedJsonError
        Naming the first field that is missing, unknown or of the wrong type.
    """
    label = path or cls.__name__
    if not isinstance(raw, dict):
        raise TypedJsonError(f"{label}: expected an object, got {_describe(raw)}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
    unknown = sorted(set(raw) - set(fields))
    if unknown:
        raise TypedJsonError(f"{label}: unknown field(s) {', '.join(map(repr, unknown))}; "
                             f"expected fields: {', '.join(fields)}")
    hints = _hints(cls)
    kwargs = {}
    for name, f in fields.items():
        sub = f"{path}.{name}" if path else name
        if name not in raw:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise TypedJsonError(f"{sub}: missing (required)")
            continue
        kwargs[name] = _convert(hints[name], raw[name], sub)
    obj = cls(**kwargs)
    check = getattr(obj, "check", None)
    if callable(check):
        try:
            check()
        except ValueError as exc:
            raise TypedJsonError(f"{label}: {exc}") from None
    return obj


def to_json(obj: object) -> Any:
    """Plain JSON value of a dataclass (recursively); enums by value, non-finite floats as null."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_json(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, enum.Enum):
        return obj.value
    if isinstance(obj, (list, tuple)):
        return [to_json(v) for v in obj]
    if isinstance(obj, dict):
        return {str(k): to_json(v) for k, v in obj.items()}
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalar
        return to_json(obj.item())
    return obj
