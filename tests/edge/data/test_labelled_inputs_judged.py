"""Labelled data and replay folders are judged when opened, before any work: frames the runtime
would refuse (grey, RGBA, 16-bit, another size) are refused by the one labelled-data reader
(AuthorsDataset) and so by every verb that reads labelled data, naming the file; a dangling
link or an unreadable file in a replay folder is bad input (exit 2) before the run starts."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.data.dataset import AuthorsDataset
from tactile_force.edge.errors import DatasetError, SourceError
from tactile_force.edge.sources import ReplayFolderSource

from benchmarks.harness.cases import make_dataset

#: image (as cv2.imwrite writes it) -> the words the refusal holds
BAD_FRAMES = {
    "grey": (np.full((320, 240), 90, np.uint8), r"grey 1-channel uint8 image"),
    "rgba": (np.full((320, 240, 4), 90, np.uint8), r"RGBA 4-channel uint8 image"),
    "16-bit": (np.full((320, 240, 3), 9000, np.uint16), r"colour 3-channel uint16 image"),
    "wrong size": (np.full((480, 640, 3), 90, np.uint8), r"shape \(480, 640, 3\); expected \(320, 240, 3\)"),
    "landscape": (np.full((240, 320, 3), 90, np.uint8), r"shape \(240, 320, 3\).*looks like landscape"),
}


def _dataset_with(root: Path, kind: str, n: int = 4, bad: int = 2) -> Path:
    """A labelled set of ``n`` good frames whose sample ``bad`` is replaced by a BAD_FRAMES image."""
    make_dataset(root, n=n)
    cv2.imwrite(str(root / "images" / f"{bad}.png"), BAD_FRAMES[kind][0])
    return root


@pytest.mark.parametrize("kind", sorted(BAD_FRAMES))
def test_the_labelled_data_reader_refuses_frames_the_runtime_would_at_open(tmp_path, kind):
    root = _dataset_with(tmp_path / "ds", kind)
    with pytest.raises(DatasetError, match=BAD_FRAMES[kind][1]) as info:
        AuthorsDataset(root)
    assert str(root / "images" / "2.png") in str(info.value)
    with pytest.raises(SourceError, match=BAD_FRAMES[kind][1]):  # a replay reads labelled data the same way
        ReplayFolderSource(root)


def test_a_palette_png_is_judged_by_what_it_decodes_to(tmp_path):
    image = pytest.importorskip("PIL.Image", reason="writing a palette PNG needs Pillow")
    root = make_dataset(tmp_path / "ds", n=2)
    frame = np.full((320, 240, 3), 90, np.uint8)
    image.fromarray(frame).convert("P").save(root / "images" / "1.png")  # colour type 3: decoded to BGR
    assert AuthorsDataset(root).load(1).frame.shape == (320, 240, 3)
    image.fromarray(frame[:, :, 0]).convert("P").resize((320, 240)).save(root / "images" / "1.png")
    with pytest.raises(DatasetError, match=r"1\.png: shape \(240, 320, 3\)"):
        AuthorsDataset(root)


def test_bench_refuses_grey_labelled_frames_before_measuring(tmp_path, capsys):
    root = _dataset_with(tmp_path / "ds", "grey")
    out = tmp_path / "bench"
    rc = cli_main(["bench", "--data", str(root), "--frames", "5", "--repeats", "1", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert str(root / "images" / "2.png") in err and "grey" in err and "Traceback" not in err
    assert not out.exists()  # refused before any work: no report


@pytest.mark.parametrize("kind", ["grey", "16-bit", "wrong size"])
def test_run_on_labelled_frames_refuses_them_at_open(tmp_path, kind, capsys):
    root = _dataset_with(tmp_path / "ds", kind)
    out = tmp_path / "r.csv"
    rc = cli_main(["run", "--source", str(root), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and str(root / "images" / "2.png") in err, err
    assert not out.exists()


def test_compress_frames_from_a_labelled_folder_are_judged_as_labelled_data(tmp_path):
    pytest.importorskip("torch", reason="compress needs the 'export' extra")
    from tactile_force.export.compress import CompressError, read_frames

    root = _dataset_with(tmp_path / "ds", "grey")
    with pytest.raises(CompressError, match=r"--frames: .*2\.png: grey 1-channel"):
        read_frames([root])


def test_quantize_calibration_refuses_a_labelled_set_with_a_grey_frame(tmp_path):
    pytest.importorskip("torch", reason="tactile_force.export needs the export extra (torch)")
    from tactile_force.export.calibration import CalibrationData, CalibrationError

    root = _dataset_with(tmp_path / "ds", "grey", n=6)
    with pytest.raises(CalibrationError, match=r"2\.png: grey 1-channel"):
        CalibrationData.from_path(root, "rgbmod", limit=1)  # judged at open, not only the frames read


# -- dangling links and unreadable files ----------------------------------------------------------
def _plain_folder(tmp_path: Path, aurova_dir: Path) -> Path:
    folder = tmp_path / "frames"
    folder.mkdir()
    for p in sorted((aurova_dir / "images").glob("*.png"))[:4]:
        shutil.copy(p, folder / p.name)
    return folder


def test_a_dangling_link_in_a_plain_replay_folder_is_refused_at_open(tmp_path, aurova_dir):
    folder = _plain_folder(tmp_path, aurova_dir)
    (folder / "zz_9999.png").symlink_to(tmp_path / "gone.png")
    with pytest.raises(SourceError, match=r"zz_9999\.png is a dangling symbolic link .*gone\.png"):
        ReplayFolderSource(folder)


def test_run_with_a_dangling_link_exits_2_before_any_reading(tmp_path, aurova_dir, capsys):
    folder = _plain_folder(tmp_path, aurova_dir)
    (folder / "zz_9999.png").symlink_to(tmp_path / "gone.png")
    out = tmp_path / "r.csv"
    rc = cli_main(["run", "--source", str(folder), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "zz_9999.png" in err and "dangling" in err and "Traceback" not in err, err
    assert not out.exists() and "readings" not in err  # refused before the run, not after it


@pytest.mark.parametrize("which", ["image", "label"])
def test_a_dangling_link_in_a_labelled_folder_is_refused_at_open(tmp_path, which):
    root = make_dataset(tmp_path / "ds", n=3)
    target = root / ("images/1.png" if which == "image" else "forces/force_1.txt")
    target.unlink()
    target.symlink_to(tmp_path / "elsewhere" / target.name)
    with pytest.raises(DatasetError, match=rf"{target.name}: a dangling symbolic link"):
        AuthorsDataset(root)
    with pytest.raises(SourceError, match="dangling symbolic link"):
        ReplayFolderSource(root)


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root reads any file")
def test_an_unreadable_frame_is_refused_at_open(tmp_path, aurova_dir):
    folder = _plain_folder(tmp_path, aurova_dir)
    locked = sorted(folder.glob("*.png"))[1]
    locked.chmod(0)
    try:
        with pytest.raises(SourceError, match=rf"{locked.name} is not readable"):
            ReplayFolderSource(folder)
    finally:
        locked.chmod(0o644)
