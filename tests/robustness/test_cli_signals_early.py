"""A Ctrl-C (or SIGTERM) at the CLI's first moments, while the package and the verb's module
are still loading, exits 130 (143) with one line and no traceback: real subprocesses,
signals sent at several delays after the process starts loading the package."""

from __future__ import annotations

import signal
import sys

import pytest

from benchmarks.robustness_cli import EARLY_DELAYS, early_signal_verbs, signal_at_start

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/PID/maps (Linux)")


@pytest.mark.parametrize("verb", ["bench", "run"])
def test_sigint_while_starting_exits_130_without_traceback(tmp_path, verb):
    args = dict(early_signal_verbs(tmp_path))[verb]
    for delay in EARLY_DELAYS:
        rc, err = signal_at_start(args, signal.SIGINT, delay)
        assert rc == 130 and "Traceback" not in err, (delay, rc, err[-600:])
        # one line while starting; on a slow host the signal may come once the verb runs: its own clean stop
        assert "interrupted" in err or "stopped by SIGINT" in err, (delay, err[-300:])
        assert not (tmp_path / "bench").exists()  # no half result


def test_sigterm_while_starting_exits_143(tmp_path):
    args = dict(early_signal_verbs(tmp_path))["run"]
    for delay in (0.0, 0.1):
        rc, err = signal_at_start(args, signal.SIGTERM, delay)
        assert rc == 143 and "Traceback" not in err, (delay, rc, err[-600:])


def test_only_the_cli_process_installs_the_early_handler():
    from tactile_force.edge._cli_start import started_as_cli

    py = sys.executable
    assert started_as_cli([py, "-m", "tactile_force.edge.cli", "run"])
    assert started_as_cli([py, "-mtactile_force.edge.cli"])
    assert started_as_cli([py, "-X", "dev", "/venv/bin/tactile-force", "bench"])
    assert not started_as_cli([py, "-m", "pytest"])
    assert not started_as_cli([py, "-c", "import tactile_force.edge"])
    assert not started_as_cli([py, "app.py", "tactile-force"])
    import tactile_force.edge  # noqa: F401 - imported here by a program that is not the CLI

    assert getattr(signal.getsignal(signal.SIGTERM), "__module__", None) != "tactile_force.edge._cli_start"
