"""The typed reader's scene features: bounds and choices declared on the field, Literal
values, paths relative to the file, unknown keys named with the allowed ones, partial
overrides of a preset. One message style: the dotted key, what was expected, what was got."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import pytest
from tactile_force.edge.typed_json import TypedJsonError, check, from_json, read_value


@dataclass
class Sensor:
    name: str = field(metadata=check(nonempty=True))
    fps: float | None = field(default=None, metadata=check(gt=0))
    mode: Literal["exact", "paper"] = "exact"
    frames: int = field(default=0, metadata=check(ge=0))
    fraction: float = field(default=0.5, metadata=check(ge=0, le=1))
    data: Path | None = None
    out: Path | None = field(default=None, metadata=check(path="output"))
    kind: str = field(default="a", metadata=check(choices=("a", "b")))


@dataclass
class Doc:
    sensor: list[Sensor] = field(default_factory=list)


@pytest.mark.parametrize("sensor, message", [
    ({"name": "l", "fps": "fast"}, "sensor[0].fps: expected a number > 0, got 'fast'"),
    ({"name": "l", "fps": 0}, "sensor[0].fps: expected a number > 0, got 0"),
    ({"name": "l", "fps": float("inf")}, "sensor[0].fps: expected a finite number > 0, got inf"),
    ({"name": "l", "fps": True}, "sensor[0].fps: expected a number > 0, got True"),
    ({"name": "l", "frames": -1}, "sensor[0].frames: expected an integer >= 0, got -1"),
    ({"name": "l", "fraction": 2}, "sensor[0].fraction: expected a number in [0, 1], got 2"),
    ({"name": "l", "mode": "fast"}, "sensor[0].mode: expected one of 'exact', 'paper', got 'fast'"),
    ({"name": "l", "kind": "c"}, "sensor[0].kind: expected one of 'a', 'b', got 'c'"),
    ({"name": ""}, "sensor[0].name: is empty; expected a non-empty string"),
    ({"name": "l", "data": ""}, "sensor[0].data: is empty; expected a path"),
    ({"fps": 1}, "sensor[0].name: missing; expected a non-empty string"),
    ({"name": "l", "fsp": 1}, "sensor[0]: unknown key 'fsp'; allowed keys: name, fps, mode, frames, fraction, data, "
                              "out, kind"),
])
def test_bad_values_name_the_dotted_key_and_what_was_expected(sensor, message):
    with pytest.raises(TypedJsonError) as info:
        from_json(Doc, {"sensor": [sensor]}, table="a table")
    assert str(info.value) == message


def test_tables_are_named_as_the_caller_says():
    with pytest.raises(TypedJsonError, match=r"^sensor\[0\]: expected a table, got 3$"):
        from_json(Doc, {"sensor": [3]}, table="a table")
    with pytest.raises(TypedJsonError, match=r"^unknown key 'x'; allowed keys: sensor$"):
        from_json(Doc, {"x": 1})


def test_paths_are_relative_to_the_base_or_the_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("TF_TEST_DIR", "/data")
    doc = from_json(Doc, {"sensor": [{"name": "l", "data": "rec", "out": "o.csv"},
                                      {"name": "r", "data": "$TF_TEST_DIR/x", "out": "/abs/o.csv"},
                                      {"name": "p", "data": "package:calib.npz"}]},
                    base=tmp_path / "scenes", prefixes={"package:": "/pkg/assets"})
    assert doc.sensor[0].data == tmp_path / "scenes" / "rec" and doc.sensor[0].out == tmp_path / "o.csv"
    assert doc.sensor[1].data == Path("/data/x") and doc.sensor[1].out == Path("/abs/o.csv")
    assert doc.sensor[2].data == Path("/pkg/assets/calib.npz")


def test_defaults_fill_what_a_partial_table_leaves_out():
    preset = Sensor(name="preset", fps=25.0, mode="paper")
    s = from_json(Sensor, {"fps": 30}, "gate", defaults=preset)
    assert (s.name, s.fps, s.mode) == ("preset", 30.0, "paper") and isinstance(s.fps, float)
    with pytest.raises(TypedJsonError, match=r"^gate\.fps: expected a number > 0, got -1$"):
        from_json(Sensor, {"fps": -1}, "gate", defaults=preset)


def test_literal_numbers_are_not_booleans_and_read_value_checks_one_value():
    assert read_value(Literal[60, 30], 30, "fps") == 30
    with pytest.raises(TypedJsonError, match=r"^fps: expected one of 60, 30, got True$"):
        read_value(Literal[60, 30], True, "fps")
    with pytest.raises(TypedJsonError, match=r"^sensor\[1\]\.source: expected one of 'camera', got 'usb'$"):
        read_value(str, "usb", "sensor[1].source", check(choices=("camera",))["typed_json"])
