"""A Ctrl-C whose KeyboardInterrupt a library swallows (OpenCV's loader wraps imports in a bare
``except``) still stops the verb: no result is published, no run goes on, exit 130 with a line.
The swallowing library is simulated in-process (a function that catches the interrupt); the
verbs, files and runtime are real."""

from __future__ import annotations

import importlib
import signal

import pytest
from tactile_force.edge.cli import Interrupted
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.files.atomic import staged_file, staged_folder
from tactile_force.edge.interrupts import CliSignals, pending, raise_pending
from tactile_force.edge.report.progress import progress

from tests.conftest import REPO


def swallow(sig: int = signal.SIGINT) -> None:
    """A library that catches everything: the signal's exception ends here."""
    try:
        signal.raise_signal(sig)
    except BaseException:  # noqa: BLE001 - the point of the test
        pass


def test_a_swallowed_signal_is_remembered_and_raised_again():
    assert pending() is None
    raise_pending()  # outside the CLI: nothing happens
    with CliSignals():
        swallow(signal.SIGTERM)
        assert pending() == signal.SIGTERM
        with pytest.raises(Interrupted) as exc:
            raise_pending()
        assert exc.value.signum == signal.SIGTERM
    assert pending() is None
    raise_pending()


def test_no_folder_or_file_is_published_after_a_swallowed_signal(tmp_path):
    with CliSignals(), pytest.raises(Interrupted):
        with staged_folder(tmp_path / "out", "bench") as tmp:
            (tmp / "result.txt").write_text("complete\n")
            swallow()
    with CliSignals(), pytest.raises(Interrupted):
        with staged_file(tmp_path / "page.md") as tmp:
            tmp.write_text("complete\n")
            swallow()
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # neither result, no staging left


def test_long_work_stops_at_its_next_step():
    done = []
    with CliSignals(), pytest.raises(Interrupted):
        for i in progress(range(100), desc="work"):
            done.append(i)
            if i == 3:
                swallow()
    assert done == [0, 1, 2, 3]


@pytest.fixture
def swallowing_import(monkeypatch):
    """The verb's module loads while a Ctrl-C comes, and a library it imports swallows it."""
    original = importlib.import_module

    def import_module(name, package=None):
        module = original(name, package)
        if name.startswith("tactile_force.edge.cli."):
            swallow()
        return module

    monkeypatch.setattr(importlib, "import_module", import_module)


def test_bench_publishes_nothing_after_a_swallowed_ctrl_c(tmp_path, swallowing_import, capsys):
    rc = cli_main(["bench", "--out", str(tmp_path / "bench"), "--frames", "20"])
    err = capsys.readouterr().err
    assert rc == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert not (tmp_path / "bench").exists()


def test_run_does_not_start_after_a_swallowed_ctrl_c(tmp_path, monkeypatch, capsys):
    from tactile_force.edge import scene

    build = scene.build_scene

    def build_scene(*args, **kwargs):
        built = build(*args, **kwargs)
        swallow()
        return built

    monkeypatch.setattr(scene, "build_scene", build_scene)
    rc = cli_main(["run", "--source", "virtual", "--max-frames", "100000", "--out", str(tmp_path / "r.csv")])
    err = capsys.readouterr().err
    assert rc == 130, err
    assert "interrupted" in err and "Traceback" not in err
    assert "RE " not in err and "stopped by" not in err  # no run, no summary
    lines = (tmp_path / "r.csv").read_text().splitlines() if (tmp_path / "r.csv").exists() else []
    assert len(lines) <= 1  # a header at most: no reading was made


def test_a_verb_that_catches_the_signal_says_so(monkeypatch, capsys):
    """The last resort: a verb that ran to its end after the signal exits 130 with a line, never 0."""
    from tactile_force.edge.cli import scene as scene_cli

    show = scene_cli.main

    def scene_main(args):
        swallow()
        return show(args)

    monkeypatch.setattr(scene_cli, "main", scene_main)
    rc = cli_main(["scene", "show", str(REPO / "edge" / "scenes" / "oak.toml")])
    err = capsys.readouterr().err
    assert rc == 130, err
    assert "interrupted by SIGINT" in err and "Traceback" not in err
