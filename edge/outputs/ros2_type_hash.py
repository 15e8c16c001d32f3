"""ROS 2 type hashes (REP-2016, ``RIHS01_<sha256 hex>``) of the messages this package encodes.

A ROS 2 node on rmw_zenoh names every topic by its type hash (the key expression and the
liveliness tokens carry it); a subscriber matches a publisher only when the hashes agree.
The hash is computed here from the ``.msg`` texts in
:data:`~tactile_force.edge.outputs.ros2_messages.MSG_DEFINITIONS` (the definitions the MCAP
schemas carry and the IDL structs encode), never typed in by hand:

- each type becomes ``{"type_name": "pkg/msg/Name", "fields": [{"name": ..., "type":
  {"type_id": ..., "capacity": ..., "string_capacity": ..., "nested_type_name": ...}}]}``,
  fields in declaration order, constants left out (REP-2016: constants and default
  values are not hashed);
- ``type_id`` is the ``type_description_interfaces/msg/FieldType`` id of the element type
  (nested 1, int8 2 ... float64 11, bool 15, byte 16, string 17, bounded string 21), plus 48
  for a fixed array, 96 for a bounded sequence, 144 for an unbounded sequence;
- the hashed document is ``{"type_description": <the type>, "referenced_type_descriptions":
  [every type it uses, directly or not, sorted by name]}`` as JSON with ``", "`` and ``": "``
  separators, ASCII only, keys in the order above; RIHS01 = sha256 of those UTF-8 bytes.
"""

from __future__ import annotations

import hashlib
import json
import re
from typing import Any

#: type_description_interfaces/msg/FieldType ids of the element types (REP-2016).
FIELD_TYPE_IDS: dict[str, int] = {
    "int8": 2, "uint8": 3, "char": 13, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8,
    "uint64": 9, "float32": 10, "float64": 11, "bool": 15, "byte": 16, "string": 17, "wstring": 18,
}
NESTED_TYPE = 1
BOUNDED_STRING = 21
BOUNDED_WSTRING = 22
ARRAY, BOUNDED_SEQUENCE, UNBOUNDED_SEQUENCE = 48, 96, 144

_SEP = re.compile(r"^={80}\nMSG: (\S+)\n", re.MULTILINE)
_FIELD = re.compile(r"^(?P<type>[A-Za-z_][A-Za-z0-9_/]*)(?:<=(?P<strcap>\d+))?(?P<array>\[(?:<=)?\d*\])?$")


def full_type_name(name: str) -> str:
    """'std_msgs/Header' -> 'std_msgs/msg/Header' (a name with three parts is kept)."""
    parts = name.split("/")
    return f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else name


def split_definition(type_name: str, text: str) -> dict[str, str]:
    """The ``.msg`` text of each type in a concatenated ``ros2msg`` definition (the message,
    then ``====...`` / ``MSG: pkg/Name`` sections), by full type name."""
    pieces = _SEP.split(text)
    out = {full_type_name(type_name): pieces[0]}
    for name, body in zip(pieces[1::2], pieces[2::2]):
        out[full_type_name(name)] = body
    return out


def _field(name: str, spec: str, where: str) -> dict[str, Any]:
    m = _FIELD.match(spec)
    if not m:
        raise ValueError(f"{where}: field {name!r}: cannot read type {spec!r}")
    base, strcap, array = m["type"], m["strcap"], m["array"]
    capacity = string_capacity = 0
    nested = ""
    if "/" in base:
        tid, nested = NESTED_TYPE, full_type_name(base)
    elif strcap is not None:
        if base not in ("string", "wstring"):
            raise ValueError(f"{where}: field {name!r}: '<=' bound on {base!r}; only strings take one")
        tid, string_capacity = (BOUNDED_STRING if base == "string" else BOUNDED_WSTRING), int(strcap)
    elif base in FIELD_TYPE_IDS:
        tid = FIELD_TYPE_IDS[base]
    else:
        raise ValueError(f"{where}: field {name!r}: unknown type {base!r}")
    if array == "[]":
        tid += UNBOUNDED_SEQUENCE
    elif array and array.startswith("[<="):
        tid, capacity = tid + BOUNDED_SEQUENCE, int(array[3:-1])
    elif array:
        tid, capacity = tid + ARRAY, int(array[1:-1])
    return {"name": name, "type": {"type_id": tid, "capacity": capacity, "string_capacity": string_capacity,
                                   "nested_type_name": nested}}


def type_fields(type_name: str, text: str) -> list[dict[str, Any]]:
    """The REP-2016 field descriptions of one ``.msg`` text (comments, blank lines and
    constants left out; an empty message gets the one ``uint8`` member ROS 2 gives it)."""
    fields = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        spec, _, rest = line.partition(" ")
        rest = rest.strip()
        if "=" in rest:  # a constant: 'byte OK=0'
            continue
        name = rest.split()[0] if rest else ""
        if not name:
            raise ValueError(f"{type_name}: line {line!r}: expected 'TYPE NAME'")
        fields.append(_field(name, spec, type_name))
    return fields or [_field("structure_needs_at_least_one_member", "uint8", type_name)]


def type_description(type_name: str, definition: str) -> dict[str, Any]:
    """The hashed REP-2016 document of ``type_name`` ('geometry_msgs/msg/WrenchStamped') from
    its concatenated ``ros2msg`` definition; ValueError when a used type is not defined there."""
    texts = split_definition(type_name, definition)
    types: dict[str, dict[str, Any]] = {name: {"type_name": name, "fields": type_fields(name, text)}
                                        for name, text in texts.items()}
    top = full_type_name(type_name)
    seen: set[str] = set()
    queue = [top]
    while queue:
        for f in types[queue.pop()]["fields"]:
            nested = f["type"]["nested_type_name"]
            if nested and nested not in seen:
                if nested not in types:
                    raise ValueError(f"{top}: uses {nested}, which its definition does not hold")
                seen.add(nested)
                queue.append(nested)
    return {"type_description": types[top], "referenced_type_descriptions": [types[n] for n in sorted(seen)]}


def rihs01(type_name: str, definition: str | None = None) -> str:
    """``RIHS01_<64 hex>`` of ``type_name``; ``definition`` default: the package's own
    (:data:`~tactile_force.edge.outputs.ros2_messages.MSG_DEFINITIONS`)."""
    if definition is None:
        from .ros2_messages import MSG_DEFINITIONS

        definition = MSG_DEFINITIONS[type_name]
    text = json.dumps(type_description(type_name, definition), ensure_ascii=True, separators=(", ", ": "),
                      allow_nan=False, sort_keys=False)
    return "RIHS01_" + hashlib.sha256(text.encode("utf-8")).hexdigest()
