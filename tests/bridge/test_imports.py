"""A CPU-only process never imports pyusb, hidapi or depthai (checked in a fresh interpreter)."""

import json
import subprocess
import sys
import textwrap

DEVICE_LIBS = ("usb", "hid", "depthai")


def _modules_after(code: str) -> set[str]:
    script = textwrap.dedent(code) + textwrap.dedent("""
        import json, sys
        print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in ('usb', 'hid', 'depthai', 'torch'))))
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def test_edge_and_its_run_command_import_no_device_library():
    loaded = _modules_after("""
        import importlib.util
        import tactile_force.edge
        from tactile_force.edge.cli import main
        if importlib.util.find_spec("tactile_force.edge.cli.run") is not None:
            try:
                main(["run", "--help"])
            except SystemExit:
                pass
    """)
    assert not loaded, f"CPU-only path imported {sorted(loaded)}"


def test_firmware_bridge_package_imports_device_libraries_lazily():
    loaded = _modules_after("import tactile_force.firmware_bridge")
    assert not loaded & set(DEVICE_LIBS), sorted(loaded)


def test_devices_command_never_imports_depthai():
    loaded = _modules_after("""
        import contextlib, io
        from tactile_force.edge.cli import main
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(["devices"]) == 0
    """)
    assert "depthai" not in loaded and "torch" not in loaded
