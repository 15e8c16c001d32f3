"""Labels validated where they enter: one grammar (a decimal comma or a
unit is an error naming the file), a FIFO label refused without blocking, duplicated or
colliding presses and non-PNG presses refused naming the files, labels that look like
another unit warned about. Through edge/data/labels.py, the dataset reader and calibrate-force."""

from __future__ import annotations

import logging
import os
import shutil
import threading
from pathlib import Path

import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.data.dataset import AuthorsDataset
from tactile_force.edge.data.labels import LabelError, read_force_file
from tactile_force.edge.errors import DatasetError
from tactile_force.edge.scene import default_bundle_path

from benchmarks.robustness import expected_label
from tests.conftest import shared_data


@pytest.mark.parametrize("data, words", [
    (b"1,08\n", "decimal comma"), (b"0,95\n", "decimal comma"), (b"12,5 N\n", "decimal comma"),
    (b"1.08 N\n", "unit"), (b"1.08N\n", "unit"), (b"108 g\n", "unit"), (b"4 kgf\n0.1\n", "unit"),
    (b"1.5 # scale\n", "text"),
])
def test_decimal_comma_and_units_are_errors_naming_the_file(tmp_path, data, words):
    p = tmp_path / "force_3.txt"
    p.write_bytes(data)
    with pytest.raises(LabelError, match=words) as info:
        read_force_file(p)
    assert "force_3.txt" in str(info.value)
    assert expected_label(data) is None  # the robustness catalogue's oracle agrees


@pytest.mark.parametrize("data, value", [(b"1.08\n", 1.08), (b"3.5,2.0\n", 3.5), (b"3.5, 0.1\n", 3.5),
                                         (b"3.5; 2.0\n", 3.5), (b"3.5 2.0\n", 3.5), (b"2e-3\n", 2e-3)])
def test_plain_numbers_and_numeric_columns_still_read(tmp_path, data, value):
    p = tmp_path / "force_0.txt"
    p.write_bytes(data)
    assert read_force_file(p) == value == expected_label(data)


def _presses(tmp_path: Path, name: str = "presses") -> Path:
    return Path(shutil.copytree(shared_data("aurova_digit_grasp"), tmp_path / name))


def test_calibrate_force_refuses_decimal_comma_labels(tmp_path, capsys):
    data = _presses(tmp_path)
    for f in sorted((data / "forces").iterdir()):
        first, *rest = f.read_text().splitlines()
        f.write_text("\n".join([f"{float(first):.2f}".replace(".", ","), *rest]) + "\n")
    rc = cli_main(["calibrate-force", str(default_bundle_path()), "--data", str(data), "--out", str(tmp_path / "c")])
    err = capsys.readouterr().err
    assert rc == 2 and "decimal comma" in err and "force_1500.txt" in err, err
    assert not (tmp_path / "c").exists()


def test_fifo_label_is_refused_without_blocking(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this platform")
    p = tmp_path / "force_0.txt"
    os.mkfifo(p)
    box: list[BaseException | float] = []

    def read() -> None:
        try:
            box.append(read_force_file(p))
        except BaseException as exc:  # noqa: BLE001 - reported below
            box.append(exc)

    t = threading.Thread(target=read, daemon=True)
    t.start()
    t.join(30)
    if t.is_alive():
        with open(p, "wb"):  # unblock the reader so the thread ends
            pass
        pytest.fail("read_force_file blocked on a FIFO")
    assert isinstance(box[0], LabelError) and "FIFO" in str(box[0]) and "force_0.txt" in str(box[0])


def test_duplicated_presses_are_refused_naming_both_files(tmp_path, capsys):
    """The 11 presses copied 3 times: leave-one-out would see each press's twins (RE ~0.001)."""
    data = _presses(tmp_path)
    for k in (1, 2):
        for img in sorted((data / "images").glob("*.png")):
            n = int(img.stem)
            shutil.copy(img, data / "images" / f"{n + 1000 * k}.png")
            shutil.copy(data / "forces" / f"force_{n}.txt", data / "forces" / f"force_{n + 1000 * k}.txt")
    out = tmp_path / "cal"
    rc = cli_main(["calibrate-force", str(default_bundle_path()), "--data", str(data), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "the same frame twice" in err and "1500.png" in err and "2500.png" in err, err
    assert not out.exists()


def test_zero_padded_name_beside_the_plain_one_is_an_error_naming_both(tmp_path):
    data = _presses(tmp_path)
    shutil.copy(data / "images" / "1502.png", data / "images" / "01500.png")
    with pytest.raises(DatasetError, match="both are sample 1500") as info:
        AuthorsDataset(data)
    assert "01500.png" in str(info.value) and "/1500.png" in str(info.value)


@pytest.mark.parametrize("name", ["1530.jpg", "1530.JPEG", "1530.PNG", "1530 (copy).png"])
def test_a_press_that_would_be_skipped_is_an_error_naming_it(tmp_path, name):
    import cv2

    data = _presses(tmp_path)
    cv2.imwrite(str(data / "images" / "x.png"), cv2.imread(str(data / "images" / "1500.png")))
    (data / "images" / "x.png").rename(data / "images" / name)
    with pytest.raises(DatasetError, match="not named N.png") as info:
        AuthorsDataset(data)
    assert name in str(info.value)


def test_hidden_temp_files_of_a_writer_are_ignored(tmp_path):
    data = _presses(tmp_path)
    (data / "images" / ".1530.png.tmp").write_bytes(b"partial")
    assert len(AuthorsDataset(data)) == 11


def test_labels_ten_times_too_large_give_a_warning_naming_the_cause(tmp_path, caplog, capsys):
    data = _presses(tmp_path)
    for f in sorted((data / "forces").iterdir()):
        first, *rest = f.read_text().splitlines()
        f.write_text("\n".join([f"{10 * float(first):.4f}", *rest]) + "\n")
    with caplog.at_level(logging.WARNING, logger="tactile_force"):
        rc = cli_main(["calibrate-force", str(default_bundle_path()), "--data", str(data),
                       "--out", str(tmp_path / "cal")])
    capsys.readouterr()
    assert rc in (0, 2)
    warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert any("another unit or scaled" in w and str(data) in w for w in warned), warned


def test_unit_problem_rules():
    from tactile_force.edge.data.labels import unit_problem

    assert unit_problem([1.08, 5.0, 11.9], "d") is None
    assert "x10" in (unit_problem([10.8, 50.0, 118.8], "d") or "")
    assert "kilograms" in (unit_problem([0.11, 0.5, 0.9], "d") or "")
    assert unit_problem([0.0, 0.0], "d") is None  # no-contact frames only: no unit to judge
