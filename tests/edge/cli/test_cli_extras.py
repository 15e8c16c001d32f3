"""Without the export extra, the torch commands say which extra to install; runtime commands still work."""

from __future__ import annotations

import subprocess
import sys

import pytest
from tactile_force.edge.scene import default_bundle_path

NO_TORCH = "import sys; sys.modules['torch'] = None; sys.modules['onnx'] = None; from tactile_force.edge.cli import main; "


@pytest.mark.parametrize("argv", [["export", "--help"], ["quantize", "--help"], ["export", "x.pth", "--out", "o"]])
def test_torch_commands_without_the_export_extra_print_one_line_and_exit_2(argv):
    run = subprocess.run([sys.executable, "-c", NO_TORCH + f"sys.exit(main({argv!r}))"],
                         capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    assert "Traceback" not in run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "'export' extra" in lines[0] and "CPU build" in lines[0]


@pytest.mark.parametrize("action", ["verify", "show"])
def test_bundle_commands_need_no_torch(action):
    run = subprocess.run([sys.executable, "-c", NO_TORCH.replace("sys.modules['onnx'] = None; ", "")
                          + f"sys.exit(main(['bundle', {action!r}, {str(default_bundle_path())!r}]))"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert "torch" not in run.stderr
