"""The catalogue's tables of cases (benchmarks/robustness_cases.toml) are complete and read as
the categories mean them: every placeholder a row uses is one its category fills, every
command row says what its refusal must name, and the categories run every row."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from benchmarks.robustness_contracts import cli_cases, targeted_manifests, targeted_scenes
from benchmarks.robustness_inputs import command_cases, depth_cases
from benchmarks.robustness_table import CASES_FILE, fill, label_tokens, rows, values

#: the placeholders each command table's category fills in
PLACES = {
    "cli_argument": {"folder", "afile", "bundle"},
    "smaller": {"folder", "replay", "vga", "pngs", "bundle"},
    "never_destroyed": {"replay", "old_csv", "old_jsonl", "old_npz", "gelsight"},
    "numeric_run": {"folder"},
}


def _words(row: dict) -> list[str]:
    out: list[str] = []
    for v in row.values():
        out += [v] if isinstance(v, str) else [w for w in v if isinstance(w, str)] if isinstance(v, list) else []
    return out


@pytest.mark.parametrize("table", sorted(PLACES))
def test_every_placeholder_is_one_the_category_fills(table):
    for row in rows(table):
        used = {m for w in _words(row) for m in re.findall(r"{(\w+)}", w)}
        assert used <= PLACES[table], f"{table}: {row} uses {used - PLACES[table]}"
        filled = fill(row["argv"], {k: f"/x/{k}" for k in PLACES[table]})
        assert not any("{" in w for w in filled), filled


@pytest.mark.parametrize("table", ["cli_argument", "smaller", "never_destroyed"])
def test_every_refusal_row_names_what_its_message_must_hold(table):
    for row in rows(table):
        assert row.get("refuse", True) is False or row.get("names"), f"{table}: {row} names nothing"


def test_a_placeholder_nobody_fills_is_an_error_not_a_literal():
    with pytest.raises(KeyError, match="nowhere"):
        fill(["run", "{nowhere}"], {"folder": "/x"})


def test_the_categories_run_every_row(tmp_path: Path):
    assert len(cli_cases(tmp_path)) == len(rows("cli_argument"))
    places = {k: tmp_path / k for k in PLACES["never_destroyed"]}
    (tmp_path / "gelsight").write_text("x")
    assert len(command_cases("never_destroyed", places)) == len(rows("never_destroyed"))
    (tmp_path / "gelsight").unlink()  # a row that needs an absent path is left out, the others kept
    assert len(command_cases("never_destroyed", places)) == len(rows("never_destroyed")) - 1
    must = sum(1 for r in rows("manifest_lie"))
    assert sum(w.startswith("MUST-REFUSE") for w, _ in targeted_manifests()) == must
    assert [w for w, _, _ in targeted_scenes()] == [r["what"] for r in rows("scene_edit")]


def test_the_depth_cases_are_every_wrong_value_on_every_sensor(tmp_path: Path):
    cases = depth_cases(tmp_path)
    if not cases:
        pytest.skip("the shared ball-press data is absent (../shared/data)")
    assert len(cases) == len(rows("depth_set")) * (len(rows("depth_wrong")) + 1)
    assert sum("(valid)" in w for w, _ in cases) == len(rows("depth_set"))


def test_label_tokens_keep_bytes_that_are_not_utf8():
    tokens = label_tokens()
    assert b"\xff\xfe3\n" in tokens and b"\xef\xbb\xbf3.5\n" in tokens and b"12\x00\n" in tokens
    assert len(tokens) == len(values("label_tokens")) == len(set(tokens))


def test_the_table_ships_with_the_package():
    text = (Path(__file__).parents[2] / "pyproject.toml").read_text()
    assert CASES_FILE.name in text
