"""Synthetic datasets: authors' layout readable by AuthorsDataset, with metadata; splits;
the synth CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tactile_force.edge import AuthorsDataset, DatasetError
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.synthetic import (
    DatasetOptions,
    ForceDistribution,
    generate_dataset,
    indenter_split,
    paper_indenter_names,
    paper_split,
    render_samples,
    split_ids,
)

META_KEYS = ("indenter", "shape", "scale", "size_mm", "stiffness", "location", "center_px", "rotation_deg",
             "force_n", "phase", "grasp", "depth_mm", "contact_area_px")


@pytest.fixture(scope="module")
def small_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("synth")
    summary = generate_dataset(root, DatasetOptions(n=40, seed=11, frames_per_grasp=4, progress=False))
    return root, summary


def test_generated_dataset_reads_back_with_metadata(small_set):
    root, summary = small_set
    ds = AuthorsDataset(root)
    assert len(ds) == summary.n == 40
    forces = ds.forces()
    assert forces.min() >= 1.0 and forces.max() <= 15.0
    for sample in (ds[0], ds[17], ds[39]):
        assert sample.frame.shape == (320, 240, 3)
        assert all(k in sample.meta for k in META_KEYS)
        assert sample.meta["force_n"] == pytest.approx(sample.force_n, abs=1e-5)
    # every paper indenter shows up once the set has >= 18 grasps
    assert set(summary.per_indenter) <= set(paper_indenter_names())
    assert sum(summary.per_indenter.values()) == 40


def test_a_subset_renders_alone_bit_for_bit_as_the_dataset_holds_it(small_set):
    root, _ = small_set
    ds = AuthorsDataset(root)
    picked = tuple(sorted({ds.meta[n]["indenter"] for n in ds.ids})[:2])
    alone = render_samples(DatasetOptions(n=40, seed=11, frames_per_grasp=4, progress=False), picked)
    want = [n for n in ds.ids if ds.meta[n]["indenter"] in picked]
    assert [n for n, *_ in alone] == want and want
    for n, frame, force, meta in alone:
        assert np.array_equal(frame, ds.load(n).frame) and force == pytest.approx(ds.forces()[ds.ids.index(n)])
        assert meta["indenter"] in picked and meta["grasp"] == ds.meta[n]["grasp"]


def test_same_seed_same_files(small_set, tmp_path):
    root, _ = small_set
    generate_dataset(tmp_path, DatasetOptions(n=6, seed=11, frames_per_grasp=4, progress=False))
    for n in range(6):
        assert (tmp_path / "images" / f"{n}.png").read_bytes() == (root / "images" / f"{n}.png").read_bytes()
        assert (tmp_path / "forces" / f"force_{n}.txt").read_text() == (root / "forces" / f"force_{n}.txt").read_text()


def test_refuses_a_used_folder(small_set):
    root, _ = small_set
    with pytest.raises(DatasetError, match="already holds images"):
        generate_dataset(root, DatasetOptions(n=2, progress=False))


def test_optional_force_tails():
    f = ForceDistribution(below_fraction=0.2, above_fraction=0.2).sample(np.random.default_rng(0), 2000)
    assert 0.15 < np.mean(f < 1.0) < 0.25 and 0.15 < np.mean(f > 15.0) < 0.25 and f.max() <= 20.0
    core = ForceDistribution().sample(np.random.default_rng(0), 2000)
    assert core.min() >= 1.0 and core.max() <= 15.0


def test_paper_splits_are_disjoint_by_indenter():
    names = set(paper_indenter_names())
    assert len(names) == 18
    splits = [paper_split(s) for s in ("S1", "S2", "S3")]
    for sp in splits:
        parts = [set(sp.train), set(sp.val), set(sp.test)]
        assert [len(p) for p in parts] == [14, 2, 2]
        assert set.union(*parts) == names
        assert not (parts[0] & parts[1] or parts[0] & parts[2] or parts[1] & parts[2])
    assert paper_split("S1") == paper_split("S1")  # seeded
    assert len({sp.test for sp in splits}) == 3  # three different folds
    with pytest.raises(ValueError, match="S4"):
        paper_split("S4")
    with pytest.raises(ValueError):
        indenter_split(["a", "b", "c"], seed=0)


def test_split_ids_follow_metadata(small_set):
    root, _ = small_set
    ds = AuthorsDataset(root)
    sp = paper_split("S2")
    parts = split_ids(ds.meta, sp)
    assert sum(len(v) for v in parts.values()) == len(ds) and not parts["other"]
    for part in ("train", "val", "test"):
        inds = {ds.meta[n]["indenter"] for n in parts[part]}
        assert inds <= set(getattr(sp, part))


def test_synth_cli(tmp_path, capsys):
    out = tmp_path / "cli"
    rc = cli_main(["synth", "--out", str(out), "--n", "5", "--seed", "2", "--no-progress",
                   "--indenters", "ball_2.35mm,pen", "--below-fraction", "0.5"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["n"] == 5 and set(summary["per_indenter"]) <= {"ball_2.35mm", "pen"}
    assert len(AuthorsDataset(out)) == 5
    assert cli_main(["synth", "--out", str(tmp_path / "x"), "--n", "2", "--indenters", "teapot",
                     "--no-progress"]) == 2
    assert "unknown indenter 'teapot'" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
