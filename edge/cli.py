"""``tactile-force``: one console script, subcommands imported lazily.

Each subcommand lives in the module that owns its work and exposes two functions,
``configure(parser)`` and ``main(args) -> int``. Only the chosen subcommand's module is
imported, so ``tactile-force run`` never imports torch and ``--help`` is instant.
"""

from __future__ import annotations

import argparse
import importlib
import sys

#: name -> (module, configure function, main function, one-line help)
COMMANDS: dict[str, tuple[str, str, str, str]] = {
    "demo": ("tactile_force.edge.cli_runtime", "configure_demo", "main_demo",
             "virtual DIGIT grasps -> embedded default model: readings, error, latency, plot (no hardware)"),
    "run": ("tactile_force.edge.cli_runtime", "configure_run", "main_run",
            "run a scene file (live sensors or replay) and stream force readings"),
    "scene": ("tactile_force.edge.cli_runtime", "configure_scene", "main_scene",
              "inspect a scene file: 'scene show FILE' prints the stages that will run"),
    "export": ("tactile_force.export.cli", "configure_export", "main_export",
               "checkpoint (.pth) + variant -> verified fp32 ONNX bundle (needs the 'export' extra)"),
    "quantize": ("tactile_force.export.cli", "configure_quantize", "main_quantize",
                 "fp32 bundle -> int8 static / int8 dynamic / fp16 bundle with error report"),
    "bundle": ("tactile_force.export.cli", "configure_bundle", "main_bundle",
               "show and verify a model bundle (manifest, hash)"),
    "synth": ("tactile_force.edge.synthetic.cli", "configure", "main",
              "generate a synthetic labelled DIGIT dataset in the authors' layout"),
    "calibrate-depth": ("tactile_force.edge.depth.cli", "configure", "main",
                        "fit a colour->normal mapping from ball presses and report its angle error"),
    "devices": ("tactile_force.firmware_bridge.cli", "configure_devices", "main_devices",
                "list attached DIGIT / GelSight Mini / OAK devices and what is wrong with them"),
    "record": ("tactile_force.firmware_bridge.cli", "configure_record", "main_record",
               "record frames with a HID reference scale's force into the authors' dataset layout"),
}


def _top_help() -> str:
    width = max(len(n) for n in COMMANDS)
    lines = [
        "usage: tactile-force COMMAND [options]   (tactile-force COMMAND --help for details)",
        "",
        "Grasping-force estimation for DIGIT / GelSight Mini tactile sensors.",
        "",
        "commands:",
    ]
    lines += [f"  {n.ljust(width)}  {h}" for n, (_, _, _, h) in COMMANDS.items()]
    lines += ["", "Start with: tactile-force demo"]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(_top_help())
        return 0
    if argv[0] in ("-V", "--version"):
        from importlib.metadata import version

        print(f"tactile-force {version('tactile-force')}")
        return 0
    name = argv[0]
    if name not in COMMANDS:
        print(f"tactile-force: unknown command {name!r}\n\n{_top_help()}", file=sys.stderr)
        return 2
    module_name, configure_name, main_name, help_line = COMMANDS[name]
    module = importlib.import_module(module_name)
    parser = argparse.ArgumentParser(prog=f"tactile-force {name}", description=help_line)
    getattr(module, configure_name)(parser)
    args = parser.parse_args(argv[1:])
    from .errors import TactileForceError

    try:
        return int(getattr(module, main_name)(args) or 0)
    except TactileForceError as exc:
        print(f"tactile-force {name}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"tactile-force {name}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
