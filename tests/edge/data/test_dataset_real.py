"""AuthorsDataset on the real AUROVA DIGIT grasp frames, incl. broken force files."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from tactile_force.edge import AuthorsDataset, DatasetError

IDS = [1500, 1502, 1504, 1506, 1508, 1510, 1512, 1514, 1516, 1520, 1524]


def test_reads_the_real_grasp(aurova_dir):
    ds = AuthorsDataset(aurova_dir)
    assert ds.ids == IDS
    forces = ds.forces()
    assert forces[0] == pytest.approx(1.0813515186309814)  # first line of force_1500.txt
    assert forces.max() == pytest.approx(11.9, abs=0.1) and forces.min() > 1.0
    s = ds.load(1508)
    assert s.frame.shape == (320, 240, 3) and s.frame.dtype == np.uint8
    assert s.depth is not None and s.depth.shape == (320, 240)
    assert s.force_n == pytest.approx(float((aurova_dir / "forces" / "force_1508.txt").read_text().split()[0]))


@pytest.fixture
def real_copy(aurova_dir, tmp_path):
    root = tmp_path / "grasp"
    shutil.copytree(aurova_dir, root)
    for p in root.rglob("*"):
        p.chmod(0o644 if p.is_file() else 0o755)
    return root


def test_missing_force_file_names_it(real_copy):
    (real_copy / "forces" / "force_1504.txt").unlink()
    ds = AuthorsDataset(real_copy)
    assert ds.load(1502).force_n > 0  # the others still read
    with pytest.raises(DatasetError, match=r"force_1504\.txt: force file missing"):
        ds.load(1504)
    with pytest.raises(DatasetError, match=r"force_1504\.txt"):
        ds.forces()


@pytest.mark.parametrize("content", ["newtons\n1.0\n", "", "nan\n"])
def test_unparsable_force_file_names_it(real_copy, content):
    (real_copy / "forces" / "force_1512.txt").write_text(content)
    with pytest.raises(DatasetError, match=r"force_1512\.txt"):
        AuthorsDataset(real_copy).load(1512)


def test_truncated_image_names_it(real_copy):
    img = real_copy / "images" / "1510.png"
    img.write_bytes(img.read_bytes()[:200])
    with pytest.raises(DatasetError, match=r"1510\.png"):
        AuthorsDataset(real_copy).load(1510)
