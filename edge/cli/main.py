"""``tactile-force``: one console script, subcommands imported lazily.

Each subcommand lives in the module that owns its work and exposes two functions,
``configure(parser)`` and ``main(args) -> int``. Only the chosen subcommand's module is
imported, so ``tactile-force run`` never imports torch and ``--help`` is instant.

One error contract for every command: exit 0 success, 1 a check failed (parity, verify,
budget; :class:`~tactile_force.edge.errors.CheckFailedError`), 2 bad input or usage (any
other TactileForceError, an OSError on a path the user gave, a missing extra, an argparse
error), 130 interrupted by SIGINT (Ctrl-C), 143 by SIGTERM. Errors are one line; ``--debug``
shows the traceback.

Both signals raise :class:`~tactile_force.edge.interrupts.Interrupted` (a ``KeyboardInterrupt``)
in the main thread, so every verb unwinds through its clean-up (a half-made output is removed,
:mod:`.atomic`); one that a library swallowed is raised again at the next checkpoint
(:mod:`tactile_force.edge.interrupts`), and a verb that catches the interrupt itself still exits
130 / 143, never 0.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys

from ..interrupts import CliSignals, raise_pending

#: name -> (module, configure function, main function, one-line help)
COMMANDS: dict[str, tuple[str, str, str, str]] = {
    "demo": ("tactile_force.edge.cli.demo", "configure", "main",
             "virtual DIGIT grasps -> embedded default model: readings, error, latency, plot (no hardware)"),
    "run": ("tactile_force.edge.cli.run", "configure", "main",
            "run a scene file (live sensors or replay) and stream force readings"),
    "scene": ("tactile_force.edge.cli.scene", "configure", "main",
              "inspect a scene file: 'scene show FILE' prints the stages that will run"),
    "export": ("tactile_force.export.cli", "configure_export", "main_export",
               "checkpoint (.pth) + variant -> verified fp32 ONNX bundle (needs the 'export' extra)"),
    "quantize": ("tactile_force.export.cli", "configure_quantize", "main_quantize",
                 "fp32 bundle -> int8 static / int8 dynamic / fp16 bundle with error report"),
    "bundle": ("tactile_force.edge.cli.bundle", "configure_bundle", "main_bundle",
               "show and verify a model bundle (manifest, hash, graph contract; no torch needed)"),
    "calibrate-force": ("tactile_force.edge.cli.calibrate_force", "configure", "main",
                        "fit a per-sensor force calibration from 10-30 labelled presses into a new bundle"),
    "compress": ("tactile_force.export.cli_compress", "configure", "main",
                 "distil a trained model into compact students on unlabelled frames; keep the best within budget"),
    "bench": ("tactile_force.edge.cli.bench", "configure", "main",
              "does each bundle meet the latency budget on this host, at what error? report + plot (no torch)"),
    "study": ("tactile_force.export.cli_study", "configure", "main",
              "quantization study of your fp32 bundle on your labelled data: error vs latency per configuration"),
    "kernels": ("tactile_force.edge.cli.kernels", "configure", "main",
                "compile the 'fast' extra's kernels once per environment (a container image: at build time)"),
    "synth": ("tactile_force.edge.cli.synth", "configure", "main",
              "generate a synthetic labelled DIGIT dataset in the authors' layout"),
    "calibrate-depth": ("tactile_force.edge.cli.calibrate_depth", "configure", "main",
                        "fit a colour->normal mapping from ball presses and report its angle error"),
    "devices": ("tactile_force.firmware_bridge.cli", "configure_devices", "main_devices",
                "list attached DIGIT / GelSight Mini / OAK devices and what is wrong with them"),
    "record": ("tactile_force.firmware_bridge.cli", "configure_record", "main_record",
               "record frames with a HID reference scale's force into the authors' dataset layout"),
}


#: top-level module -> the extra that provides it (a missing one gives one line and exit 2)
_EXTRA_OF = {"torch": "export", "onnx": "export", "onnxscript": "export", "usb": "usb", "hid": "usb",
             "depthai": "oak", "matplotlib": "bench", "cyclonedds": "ros2", "mcap": "mcap",
             "numba": "fast", "scipy": "paper"}
_EXTRA_HINT = {
    "export": ("Install torch's CPU build first (pip install torch with the CPU-only wheel index that PyTorch's "
               "install page gives for your platform; a plain 'pip install torch' pulls a multi-GB CUDA build), "
               "then: pip install 'tactile-force[export]'"),
    "usb": "Install it with: pip install 'tactile-force[usb]'",
    "oak": "Install it with: pip install 'tactile-force[oak]'",
    "bench": "Install it with: pip install 'tactile-force[bench]'",
    "ros2": "Install it with: pip install 'tactile-force[ros2]'",
    "mcap": "Install it with: pip install 'tactile-force[mcap]'",
    "fast": "Install it with: pip install 'tactile-force[fast]'",
    "paper": "Install it with: pip install 'tactile-force[paper]'",
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


def _exit_code(exc: BaseException) -> tuple[int, str]:
    """(exit code, one-line message) for an exception a command raised: 1 a check failed,
    2 bad input or usage (a TactileForceError, an OSError on a path the user gave, a missing
    extra); anything else is a bug: 1 with a hint to rerun with --debug."""
    from ..errors import CheckFailedError, TactileForceError

    if isinstance(exc, CheckFailedError):
        return 1, f"FAILED: {exc}"
    if isinstance(exc, TactileForceError):
        return 2, f"error: {exc}"
    if isinstance(exc, ModuleNotFoundError):
        extra = _EXTRA_OF.get((exc.name or "").split(".")[0])
        if extra is not None:
            return 2, f"needs the '{extra}' extra ({exc.name} is not installed). {_EXTRA_HINT[extra]}"
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if exc.filename else ""
        return 2, f"error: {where}{exc.strerror or exc}"
    return 1, (f"internal error: {type(exc).__name__}: {exc} "
               "(please report it; rerun with --debug for the traceback)")


def flag_named(message: str, parser: argparse.ArgumentParser) -> str:
    """``message`` led by the flag the user typed when it names a parameter the flag sets
    (``VirtualDigitSource.seed=-1: ...`` -> ``--seed: VirtualDigitSource.seed=-1: ...``): an
    error from a constructor or options record the verb built from the flags names the flag."""
    import re

    for action in parser._actions:  # argparse keeps its options here; no public accessor
        flags = [f for f in action.option_strings if f.startswith("--")]
        if not flags or action.dest in ("help", "force") or any(f in message for f in flags):
            continue
        if re.search(rf"\b\w+\.{re.escape(action.dest)}\b(?![.\w])", message):
            return f"{flags[0]}: {message}"
    return message


def path_flag_named(message: str, exc: OSError, args: argparse.Namespace, parser: argparse.ArgumentParser) -> str:
    """``message`` led by the flag and path the user gave when the failing file ``exc.filename`` is that
    path or lies under it (``--out results: error: results/.report.json: Permission denied``); the output
    flags first, so a full disk under ``--out`` names ``--out`` even when an input sits beside it."""
    import os
    from pathlib import Path

    if not exc.filename:  # a write into an open file (a full disk): the outputs the user gave are where
        import errno

        outs = getattr(args, "out", None)
        outs = [o for o in (outs if isinstance(outs, list) else [outs]) if o]
        if outs and exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EIO):
            return f"--out {', '.join(str(o) for o in outs)}: {message} (while writing the outputs)"
        return message
    failed = Path(os.path.abspath(os.fsdecode(exc.filename)))
    found = []
    for action in parser._actions:  # argparse keeps its options here; no public accessor
        flags = [f for f in action.option_strings if f.startswith("--")]
        values = getattr(args, action.dest, None)
        for value in values if isinstance(values, list) else [values]:
            if flags and isinstance(value, (str, os.PathLike)) and str(value):
                given = Path(os.path.abspath(os.fspath(value)))
                staged = failed.parent == given.parent and failed.name.startswith(f".{given.name}.")  # its staging
                if failed == given or given in failed.parents or staged or (given.parent == failed and
                                                                           flags[0] == "--out"):
                    found.append((flags[0] != "--out", -len(given.parts), flags[0], value))
    if not found:
        return message
    _, _, flag, value = min(found)
    return f"{flag} {value}: {message}"


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand. Exit codes: 0 success, 1 a check failed, 2 bad input or usage,
    130 interrupted (SIGINT), 143 terminated (SIGTERM). ``--debug`` (anywhere, or
    TACTILE_FORCE_DEBUG=1) shows tracebacks.

    The signal handlers are the first thing installed, before the verb's module is imported,
    so a Ctrl-C at any moment exits 130 with one line (in a process started as the CLI,
    :mod:`tactile_force.edge._cli_start` covers the moments before this function runs)."""
    signals = CliSignals()
    name = "(starting)"
    try:
        with signals:
            argv = list(sys.argv[1:] if argv is None else argv)
            name = argv[0] if argv and argv[0] in COMMANDS else name
            return _run(argv, signals)
    except KeyboardInterrupt as exc:
        print(f"tactile-force {name}: interrupted; nothing half-made was kept", file=sys.stderr)
        return signals.code(exc)
    except BaseException:
        if signals.received is not None:  # an error raised while unwinding from a signal
            print(f"tactile-force {name}: interrupted while stopping", file=sys.stderr)
            return signals.code()
        raise


def _run(argv: list[str], signals: CliSignals) -> int:
    """:func:`main` inside the signal handlers."""
    import os

    debug = "--debug" in argv or os.environ.get("TACTILE_FORCE_DEBUG", "") not in ("", "0")
    argv = [a for a in argv if a != "--debug"]
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
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:  # ModuleNotFoundError, or MissingExtraError from a package's own check
        if signals.received is not None:  # an import cut short by the signal
            raise
        from ..errors import MissingExtraError

        missing = exc.module if isinstance(exc, MissingExtraError) else (exc.name or "")
        extra = _EXTRA_OF.get(missing.split(".")[0])
        if extra is None or debug:
            raise
        print(f"tactile-force {name}: needs the '{extra}' extra ({missing} is not installed). {_EXTRA_HINT[extra]}",
              file=sys.stderr)
        return 2
    raise_pending()  # a signal whose exception a library swallowed while the verb's module loaded
    parser = argparse.ArgumentParser(prog=f"tactile-force {name}", description=help_line,
                                     epilog="--debug: show the traceback of an error")
    getattr(module, configure_name)(parser)
    try:
        args = parser.parse_args(argv[1:])
    except SystemExit as exc:  # usage errors (2) and --help (0), also when called in-process
        return exc.code if isinstance(exc.code, int) else 2
    raise_pending()
    try:
        code = int(getattr(module, main_name)(args) or 0)
    except KeyboardInterrupt:
        raise
    except Exception as exc:  # the error contract: one line, no traceback (--debug shows it)
        if signals.received is not None:  # an error raised while unwinding from a signal
            raise
        if debug:
            raise
        code, message = _exit_code(exc)
        if isinstance(exc, OSError):
            message = path_flag_named(message, exc, args, parser)
        out = getattr(args, "out", None)
        if out is not None and not isinstance(out, list):  # the library's name for the folder a verb writes
            message = message.replace(f"bundle destination {out}:", f"--out {out}:")
        print(f"tactile-force {name}: {flag_named(message, parser)}", file=sys.stderr)
        return code
    if signals.received is not None:  # the verb, or a library it called, caught the interrupt: never a success
        print(f"tactile-force {name}: interrupted by {signal.Signals(signals.received).name}; code inside the "
              "command caught the signal, so it ran on to its end", file=sys.stderr)
        return signals.code()
    return code


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
