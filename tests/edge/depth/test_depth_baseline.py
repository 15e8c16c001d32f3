import numpy as np
import pytest
from tactile_force.edge.data.dataset import AuthorsDataset
from tactile_force.edge.data.metrics import relative_error
from tactile_force.edge.depth import MaxDeformationBaseline


def test_baseline_fits_authors_depth(aurova_dir, tmp_path):
    ds = AuthorsDataset(aurova_dir, require_depth=True)
    samples = list(ds)
    model = MaxDeformationBaseline.fit([s.depth for s in samples], [s.force_n for s in samples])
    pred = np.array([model.predict(s.depth) for s in samples])
    truth = np.array([s.force_n for s in samples])
    assert np.mean(relative_error(pred, truth)) < 0.3
    again = MaxDeformationBaseline.load(model.save(tmp_path / "b.json"))
    assert again.predict(samples[3].depth) == pytest.approx(pred[3])


def test_baseline_needs_enough_frames():
    with pytest.raises(ValueError, match="distinct"):
        MaxDeformationBaseline.fit([np.zeros((4, 4))] * 5, [1, 2, 3, 4, 5])
