"""The robustness catalogue's tables of cases, read from ``robustness_cases.toml`` beside this
module: the rows (command lines with placeholders, values to set, values to draw from) are data;
the probes that judge them stay in the category modules."""

from __future__ import annotations

import codecs
import functools
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser from PyPI (a core dependency there)
    import tomli as tomllib

CASES_FILE = Path(__file__).with_name("robustness_cases.toml")


@functools.cache
def _tables() -> dict[str, Any]:
    with CASES_FILE.open("rb") as f:
        return tomllib.load(f)


def rows(table: str) -> list[dict[str, Any]]:
    """The rows of ``[[table]]`` (copies: a caller may edit them)."""
    found = _tables().get(table)
    if not isinstance(found, list):
        raise KeyError(f"{CASES_FILE.name} has no [[{table}]] rows")
    return [dict(r) for r in found]


def section(name: str) -> dict[str, Any]:
    """The ``[name]`` table."""
    found = _tables().get(name)
    if not isinstance(found, dict):
        raise KeyError(f"{CASES_FILE.name} has no [{name}] table")
    return dict(found)


def values(key: str) -> list[Any]:
    """``[values] key``: the values a generated category draws from."""
    return list(section("values")[key])


def label_tokens() -> list[bytes]:
    """The label file contents (``[values] label_tokens``, Python byte escapes) as bytes."""
    return [codecs.escape_decode(t.encode("latin-1"))[0] for t in values("label_tokens")]


def set_at(tree: Any, path: list[Any], value: Any) -> None:
    """Set ``value`` in nested dicts / lists ``tree`` at ``path`` (keys and indices)."""
    for k in path[:-1]:
        tree = tree[k]
    tree[path[-1]] = value


def fill(value: Any, places: Mapping[str, object]) -> Any:
    """``value`` (a word, a list of them, or any other value, kept) with every ``{name}`` in its
    words replaced by ``places[name]``."""
    if isinstance(value, str):
        return value.format_map({k: str(v) for k, v in places.items()})
    if isinstance(value, list):
        return [fill(v, places) for v in value]
    return value


__all__ = ["CASES_FILE", "fill", "label_tokens", "rows", "section", "set_at", "values"]
