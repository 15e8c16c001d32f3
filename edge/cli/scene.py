"""``tactile-force scene show FILE``: the stages a scene will build, after every check ``run``
makes before it opens a device; exit 2 when ``run`` would refuse the scene."""

from __future__ import annotations

import argparse
import sys


def configure(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True)
    show = sub.add_parser("show", help="print the stages the scene will run and make every check 'run' makes before "
                                       "it opens a device (opens no device, loads no model); exit 2, as 'run' would, "
                                       "when it would refuse the scene")
    show.add_argument("file", help="scene TOML file")
    show.add_argument("--force", action="store_true",
                      help="check as 'run --force' would (existing outputs may be replaced, never an input)")


def main(args: argparse.Namespace) -> int:
    from ..scene import describe_scene, load_scene
    from ..scene.preflight import run_refusals

    scene = load_scene(args.file, check=False)
    print("\n".join(describe_scene(scene)))
    problems = run_refusals(scene, args.file, force=getattr(args, "force", False))
    for p in problems:
        print(f"error: {p}", file=sys.stderr)
    if problems:
        print(f"scene {scene.origin}: {len(problems)} problem(s); 'tactile-force run' would stop on them (exit 2)",
              file=sys.stderr)
        return 2
    return 0
