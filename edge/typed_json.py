"""Typed records: dataclasses to and from plain JSON / TOML values, validated by their annotations.

One reader serves every typed record a user or the package writes: the bundle manifest
(JSON) and its sections, scene files (TOML) and the scene the CLI builds from flags. Each
field is checked against its type annotation and the constraints declared on it, and an
error names the dotted path of the field in one style, e.g.
``model.json: error.vs_truth.re_mean: expected a number, got 'abc'`` or
``scene.toml: sensor[0].fps: expected a number > 0, got 'fast'``
(the caller prefixes the file; the reader gives the rest).

Supported annotations: ``str``, ``int``, ``float`` (finite; write ``None`` for "not
measured"), ``bool``, :class:`pathlib.Path`, ``str``-valued :class:`enum.Enum` subclasses,
``typing.Literal[...]`` (enum-like strings or numbers), ``list[X]``, ``dict[str, X]``,
``typing.Any``, unions such as ``X | None`` or ``str | float``, and nested dataclasses.

Constraints are declared on the field, one documented way::

    fps: float | None = field(default=None, metadata=check(gt=0))
    threads: int = field(default=1, metadata=check(ge=1))
    path: Path = field(metadata=check(expected="a replay folder"))         # input path
    out: Path | None = field(default=None, metadata=check(path="output"))  # output path
    source: str = field(metadata=check(choices=("camera", "replay")))

(see :func:`check`). ``Path`` fields are read from non-empty strings with ``~`` and
``$VARS`` expanded (a variable that is not set, or set to "", is an error naming it, never
left in the path or expanded to nothing): input paths relative to the ``base`` folder given
to :func:`from_json` (the scene file's folder), or under a ``prefixes`` root (``package:FILE``); output paths
(``check(path="output")``) relative to the working directory.

A dataclass may define ``check(self) -> None`` raising ``ValueError`` for rules that span
fields; the message is prefixed with the dataclass's path.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import enum
import math
import os
import re
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, TypeVar, Union

from .errors import ArgumentTypeError, TactileForceError

T = TypeVar("T")

#: The metadata key :func:`check` stores its :class:`Check` under.
METADATA_KEY = "typed_json"


class TypedJsonError(TactileForceError, ValueError):
    """A value does not fit the typed record; ``str()`` names the field path."""


@dataclass(frozen=True)
class Check:
    """Constraints on one field beyond its type (see :func:`check`)."""

    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    choices: tuple[Any, ...] | None = None
    nonempty: bool = False
    path: Literal["input", "output"] = "input"
    test: Callable[[Any], bool] | None = None
    expected: str = ""

    def range_text(self) -> str:
        parts = [f"{op} {_num(v)}" for op, v in ((">", self.gt), (">=", self.ge), ("<", self.lt), ("<=", self.le))
                 if v is not None]
        if len(parts) == 2 and self.ge is not None and self.le is not None:
            return f"in [{_num(self.ge)}, {_num(self.le)}]"
        return " and ".join(parts)

    def in_range(self, v: float) -> bool:
        return ((self.gt is None or v > self.gt) and (self.ge is None or v >= self.ge)
                and (self.lt is None or v < self.lt) and (self.le is None or v <= self.le))


NO_CHECK = Check()


def check(*, gt: float | None = None, ge: float | None = None, lt: float | None = None, le: float | None = None,
          choices: tuple[Any, ...] | None = None, nonempty: bool = False,
          path: Literal["input", "output"] = "input", test: Callable[[Any], bool] | None = None,
          expected: str = "") -> dict[str, Check]:
    """Field metadata declaring constraints: ``field(default=..., metadata=check(gt=0))``.

    Parameters
    ----------
    gt, ge, lt, le
        Bounds on a number (``int`` or ``float`` values; other members of a union are not
        range-checked).
    choices
        The allowed values (for a set known only at run time; else use ``Literal``).
    nonempty
        A string (or list) must not be empty.
    path
        For ``Path`` fields: ``"input"`` (relative to the reader's ``base``; default) or
        ``"output"`` (relative to the working directory).
    test
        An extra predicate on the converted value; ``expected`` says what it wants.
    expected
        What is expected, in words, replacing the description derived from the type and
        bounds in messages (e.g. ``"a camera index or a /dev/videoN path"``).

    Returns
    -------
    The mapping to pass as ``dataclasses.field(metadata=...)``.
    """
    return {METADATA_KEY: Check(gt, ge, lt, le, choices, nonempty, path, test, expected)}


@dataclass(frozen=True)
class _Context:
    base: Path | None
    prefixes: Mapping[str, Path]
    table: str


def _num(v: float) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _describe(value: object) -> str:
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _fail(path: str, msg: str) -> TypedJsonError:
    return TypedJsonError(f"{path}: {msg}" if path else msg)


def _expect(tp: Any, chk: Check, ctx: _Context, value: object, path: str) -> TypedJsonError:
    return _fail(path, f"expected {describe_type(tp, chk, ctx.table)}, got {_describe(value)}")


def describe_type(tp: Any, chk: Check = NO_CHECK, table: str | None = "an object") -> str:
    """What a value of annotation ``tp`` with constraints ``chk`` must be, in words
    (``"a number > 0"``, ``"one of 'cpu', 'oak'"``, ``"a list of an integer"``).

    ``table`` names a nested object (``"an object"`` in JSON, ``"a table"`` in TOML); None
    names Python values instead (``"a GateOptions"``, ``"None"``), for argument checks."""
    if chk.expected:
        return chk.expected
    if chk.choices is not None:
        return "one of " + ", ".join(map(repr, chk.choices))
    origin = typing.get_origin(tp)
    rng = chk.range_text()
    if origin in (Union, types.UnionType):
        return " or ".join(describe_type(a, chk, table) for a in typing.get_args(tp))
    if origin is Literal:
        return "one of " + ", ".join(map(repr, typing.get_args(tp)))
    if origin is list:
        return f"a list of {describe_type(typing.get_args(tp)[0], NO_CHECK, table)}"
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a tuple of {describe_type(args[0], NO_CHECK, table)}"
        return f"a tuple of {len(args)} values ({', '.join(describe_type(a, NO_CHECK, table) for a in args)})"
    if origin is collections.abc.Callable or tp is collections.abc.Callable:
        return "a callable"
    if tp is type(None):
        return "null" if table is not None else "None"
    if origin is dict or (isinstance(tp, type) and dataclasses.is_dataclass(tp)):
        if table is not None:
            return table
        return "a dict" if origin is dict else f"a {tp.__name__}"
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return "one of " + ", ".join(repr(m.value) for m in tp)
    if tp in (int, float):
        return ("an integer" if tp is int else "a number") + (f" {rng}" if rng else "")
    if tp is Path or tp is os.PathLike:
        return "an output file path" if chk.path == "output" else "a path"
    if tp in (bool, str):
        return {bool: "true or false", str: "a non-empty string" if chk.nonempty else "a string"}[tp]
    return f"a {tp.__name__}" if isinstance(tp, type) else repr(tp)


def _literal(tp: Any, value: object) -> bool:
    return any(type(value) is type(a) and value == a for a in typing.get_args(tp))


#: ``$NAME`` or ``${NAME}``, as :func:`os.path.expandvars` finds them.
_VARIABLE = re.compile(r"\$(\w+|\{([^}]*)\})", re.ASCII)


def unset_variable(text: str) -> str | None:
    """The first ``$NAME`` / ``${NAME}`` in ``text`` that is not set in the environment, or
    is set to the empty string (as written, e.g. ``"$OUT_DIR"``), else None.
    :func:`os.path.expandvars` leaves an unset variable in the path as it is, and an empty one
    turns ``$DATA/backgrounds`` into ``/backgrounds``: either way the path would point
    somewhere the user did not mean."""
    for m in _VARIABLE.finditer(text):
        name = m.group(2) if m.group(2) is not None else m.group(1)
        if not os.environ.get(name):
            return m.group(0)
    return None


def expand_path(text: str) -> Path:
    """``text`` with ``~`` and ``$VARS`` expanded; ValueError naming the variable when one is
    not set or empty (see :func:`unset_variable`)."""
    if (var := unset_variable(text)) is not None:
        state = "is empty" if os.environ.get(var.strip("${}")) == "" else "is not set"
        raise ValueError(f"environment variable {var} {state} (in {text!r}); set it, or write the path out")
    return Path(os.path.expandvars(os.path.expanduser(text)))


def _path(value: str, chk: Check, ctx: _Context) -> Path:
    for prefix, root in ctx.prefixes.items():
        if value.startswith(prefix):
            return root / value[len(prefix):]
    p = expand_path(value)
    if chk.path == "output":
        return p.absolute()
    if p.is_absolute() or ctx.base is None:
        return p
    return ctx.base / p


def _convert(tp: Any, value: object, path: str, chk: Check, ctx: _Context) -> Any:
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        options = typing.get_args(tp)
        if value is None:
            if type(None) in options:
                return None
            raise _fail(path, f"is null; expected {describe_type(tp, chk, ctx.table)}")
        errors = []
        for option in options:
            if option is type(None):
                continue
            try:
                return _convert(option, value, path, chk, ctx)
            except TypedJsonError as exc:
                errors.append(exc)
        if len(errors) == 1:
            raise errors[0]
        raise _expect(tp, chk, ctx, value, path)
    if origin is Literal:
        if not _literal(tp, value):
            raise _expect(tp, chk, ctx, value, path)
        return value
    if origin is list:
        (item,) = typing.get_args(tp)
        if not isinstance(value, list):
            raise _expect(tp, chk, ctx, value, path)
        if chk.nonempty and not value:
            raise _fail(path, f"is empty; expected {describe_type(tp, chk, ctx.table)}")
        return [_convert(item, v, f"{path}[{i}]", NO_CHECK, ctx) for i, v in enumerate(value)]
    if origin is dict:
        _, item = typing.get_args(tp)
        if not isinstance(value, dict):
            raise _expect(tp, chk, ctx, value, path)
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise _fail(path, f"key {_describe(k)} is not a string")
            out[k] = _convert(item, v, f"{path}.{k}", NO_CHECK, ctx)
        return out
    if tp is Any:
        return value
    if isinstance(tp, type) and dataclasses.is_dataclass(tp):
        return _from_json(tp, value, path, ctx, None)
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        try:
            return tp(value)
        except ValueError:
            raise _expect(tp, chk, ctx, value, path) from None
    if tp is bool:
        if not isinstance(value, bool):
            raise _expect(tp, chk, ctx, value, path)
        return value
    if tp in (int, float):
        ok = not isinstance(value, bool) and isinstance(value, (int, float) if tp is float else int)
        if not ok:
            raise _expect(tp, chk, ctx, value, path)
        assert isinstance(value, (int, float))
        if not math.isfinite(value):
            rng = chk.range_text()
            want = chk.expected or ("a finite number" + (f" {rng}" if rng else ""))
            raise _fail(path, f"expected {want}, got {value}")
        if not chk.in_range(value):
            raise _expect(tp, chk, ctx, value, path)
        out_num = float(value) if tp is float else value
        return _checked(out_num, tp, chk, ctx, path, value)
    if tp is str or tp is Path:
        if not isinstance(value, str):
            raise _expect(tp, chk, ctx, value, path)
        if not value and (chk.nonempty or tp is Path):
            raise _fail(path, f"is empty; expected {describe_type(tp, chk, ctx.table)}")
        if chk.choices is not None and value not in chk.choices:
            raise _expect(tp, chk, ctx, value, path)
        if tp is Path:
            try:
                return _checked(_path(value, chk, ctx), tp, chk, ctx, path, value)
            except ValueError as exc:  # an unset $VARIABLE
                raise _fail(path, str(exc)) from None
        return _checked(value, tp, chk, ctx, path, value)
    raise TypeError(f"{path}: typed_json does not support the annotation {tp!r}")  # a bug in a record class


def _checked(out: Any, tp: Any, chk: Check, ctx: _Context, path: str, raw: object) -> Any:
    if chk.test is not None and not chk.test(out):
        raise _expect(tp, chk, ctx, raw, path)
    return out


_HINTS: dict[type, dict[str, Any]] = {}


def type_hints(cls: type) -> dict[str, Any]:
    """The evaluated field annotations of dataclass ``cls`` (cached per class)."""
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def field_check(f: dataclasses.Field) -> Check:
    """The :class:`Check` declared on a dataclass field (no constraint: an empty Check)."""
    chk = f.metadata.get(METADATA_KEY, NO_CHECK)
    return chk if isinstance(chk, Check) else NO_CHECK


def unknown_keys(raw: Mapping[str, object], allowed: typing.Iterable[str], path: str = "") -> TypedJsonError | None:
    """The error for keys of ``raw`` outside ``allowed`` (naming them and the allowed ones), else None."""
    allowed = list(allowed)
    unknown = [k for k in raw if k not in allowed]
    if not unknown:
        return None
    what = "unknown key" if len(unknown) == 1 else "unknown keys"
    return _fail(path, f"{what} {', '.join(map(repr, unknown))}; allowed keys: {', '.join(allowed)}")


def _from_json(cls: type[T], raw: object, path: str, ctx: _Context, defaults: T | None) -> T:
    if not isinstance(raw, dict):
        raise _fail(path, f"expected {ctx.table}, got {_describe(raw)}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
    if (err := unknown_keys(raw, fields, path)) is not None:
        raise err
    hints = type_hints(cls)
    kwargs = {}
    for name, f in fields.items():
        sub = f"{path}.{name}" if path else name
        chk = field_check(f)
        if name not in raw:
            if defaults is None and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise _fail(sub, f"missing; expected {describe_type(hints[name], chk, ctx.table)}")
            continue
        kwargs[name] = _convert(hints[name], raw[name], sub, chk, ctx)
    try:  # a record that checks its own fields on construction (__post_init__) names them
        obj = dataclasses.replace(defaults, **kwargs) if defaults is not None else cls(**kwargs)  # type: ignore[type-var]
    except (ArgumentTypeError, ValueError) as exc:
        raise _fail(path, str(exc)) from None
    fn = getattr(obj, "check", None)
    if callable(fn):
        try:
            fn()
        except ValueError as exc:
            raise _fail(path, str(exc)) from None
    return obj


def from_json(cls: type[T], raw: object, path: str = "", *, base: str | os.PathLike | None = None,
              prefixes: Mapping[str, str | os.PathLike] | None = None, defaults: T | None = None,
              table: str = "an object") -> T:
    """Build dataclass ``cls`` from a parsed JSON / TOML value, checking every field.

    Parameters
    ----------
    cls
        A dataclass whose field annotations are among the supported kinds.
    raw
        The parsed value (a dict for a dataclass).
    path
        The dotted path of ``raw`` in its document (``""`` for the whole document); errors
        name ``path.field``. The caller prefixes the file name (``model.json: ...``).
    base
        The folder relative input ``Path`` fields are resolved against (a scene file's
        folder); None leaves relative input paths as written.
    prefixes
        Path prefixes mapped to folders, e.g. ``{"package:": ASSETS_DIR}``.
    defaults
        An instance of ``cls`` whose values fill the fields ``raw`` leaves out (a partial
        override of a preset); None: the dataclass defaults, required fields must be given.
    table
        How an object is named in messages (``"an object"`` for JSON, ``"a table"`` for TOML).

    Returns
    -------
    An instance of ``cls``.

    Raises
    ------
    TypedJsonError
        Naming the first field that is missing, unknown, of the wrong type or out of range.
    """
    ctx = _Context(Path(base) if base is not None else None,
                   {k: Path(v) for k, v in (prefixes or {}).items()}, table)
    return _from_json(cls, raw, path, ctx, defaults)


def read_value(tp: Any, value: object, path: str, chk: Check = NO_CHECK, *, base: str | os.PathLike | None = None,
               prefixes: Mapping[str, str | os.PathLike] | None = None, table: str = "an object") -> Any:
    """One value checked against annotation ``tp`` and constraints ``chk`` (as a field of
    :func:`from_json` would be); TypedJsonError naming ``path`` otherwise."""
    ctx = _Context(Path(base) if base is not None else None,
                   {k: Path(v) for k, v in (prefixes or {}).items()}, table)
    return _convert(tp, value, path, chk, ctx)


def to_json(obj: object) -> Any:
    """Plain JSON value of a dataclass (recursively); enums by value, paths as strings,
    non-finite floats as null."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_json(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, enum.Enum):
        return obj.value
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (list, tuple)):
        return [to_json(v) for v in obj]
    if isinstance(obj, dict):
        return {str(k): to_json(v) for k, v in obj.items()}
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if hasattr(obj, "item") and callable(obj.item):  # numpy scalar
        return to_json(obj.item())
    return obj
