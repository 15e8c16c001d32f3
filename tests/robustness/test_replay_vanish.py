"""A replay folder that disappears mid-run ends with a clear SourceError; it is not counted as
hundreds of corrupt frames while the runtime idles (9ed225d: 938 'corrupt' frames, no error)."""

from __future__ import annotations

import shutil

import pytest
from tactile_force.edge.errors import SourceError
from tactile_force.edge.sources import ReplayFolderSource

from benchmarks.robustness import make_dataset, probe_replay_vanish


@pytest.mark.parametrize("paced", [False, True])
def test_vanished_replay_folder_is_a_clear_error(tmp_path, paced):
    v = probe_replay_vanish(tmp_path, paced)
    assert v.ok, v


def test_no_frame_counted_corrupt_after_the_folder_is_gone(tmp_path):
    root = make_dataset(tmp_path / "ds", n=5)
    src = ReplayFolderSource(root, fps=None)
    assert src.read() is not None
    shutil.rmtree(root)
    with pytest.raises(SourceError, match="disappeared"):
        src.read()
    assert src.stats.corrupt == 0


def test_a_corrupt_frame_is_still_only_skipped(tmp_path):
    root = make_dataset(tmp_path / "ds", n=3)
    (root / "images" / "1.png").write_bytes(b"not a png")
    src = ReplayFolderSource(root, fps=None)
    assert [tf.index for tf in src] == [0, 2] and src.stats.corrupt == 1
