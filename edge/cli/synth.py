"""``tactile-force synth``: generate a synthetic labelled DIGIT dataset (authors' layout).

    tactile-force synth --out data/synth --n 5000 --seed 0
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from ..limits import COUNT, FRACTION, SEED
from .args import within


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of the synth command."""
    parser.add_argument("--out", required=True, help="output folder (new or empty; written whole when done)")
    parser.add_argument("--force", action="store_true", help="replace --out when it holds an earlier synth dataset")
    parser.add_argument("--n", type=within(int, COUNT), default=1000, help="number of samples (default 1000)")
    parser.add_argument("--seed", type=within(int, SEED), default=0, help="random seed (same seed -> same files)")
    parser.add_argument("--indenters", default="paper",
                        help="'paper' (the 18 paper-like indenters), 'all', or comma-separated names")
    parser.add_argument("--frames-per-grasp", type=within(int, COUNT), default=8,
                        help="samples sharing one pose (default 8)")
    parser.add_argument("--edge-fraction", type=within(float, FRACTION), default=0.15,
                        help="share of contacts near a border")
    parser.add_argument("--below-fraction", type=within(float, FRACTION), default=0.0, help="share of samples in 0-1 N")
    parser.add_argument("--above-fraction", type=within(float, FRACTION), default=0.0,
                        help="share of samples in 15-20 N")
    parser.add_argument("--no-contact-fraction", type=within(float, FRACTION), default=0.0, help="share of 0 N frames")
    parser.add_argument("--background", default=None, help="no-contact DIGIT frame to render on (default: shipped)")
    parser.add_argument("--normal-to-rgb-mlp", default=None,
                        help="FOTS normal->colour MLP .npz to shade with instead of the analytic LED model")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


#: bytes a sample takes at least (a 320x240 PNG of a DIGIT frame is 100-120 kB; the label, a few bytes)
SAMPLE_BYTES_MIN = 64 * 1024


def _inputs(args: argparse.Namespace) -> list[tuple[str, str | None]]:
    return [("--background", args.background), ("--normal-to-rgb-mlp", args.normal_to_rgb_mlp)]


def _problems(args: argparse.Namespace) -> list[str]:
    """What is wrong with the arguments (before anything is rendered), one line each."""
    out: list[str] = []
    # --n, --frames-per-grasp and the shares are range-checked by the parser (edge/limits.py)
    if args.below_fraction + args.above_fraction > 1.0:
        out.append("--below-fraction + --above-fraction add up to more than 1")
    dest = Path(args.out)
    from ..files.claim import preflight
    from ..files.guard import OutputKind, OutputRefused, check_output

    # a new or empty folder, or (--force) an earlier synth dataset (proved when claimed); never an
    # input; not a link, a mount point, under a read-only or unwritable parent, nor larger than the free space
    try:
        check_output(dest, _inputs(args), force=args.force, kind=OutputKind.FOLDER)
        preflight(dest, "--out", args.n * SAMPLE_BYTES_MIN if args.n >= 1 else None)
    except OutputRefused as exc:
        out.append(str(exc))
    for flag in ("background", "normal_to_rgb_mlp"):
        v = getattr(args, flag)
        if v is not None and not Path(v).is_file():
            out.append(f"--{flag.replace('_', '-')} {v}: file not found")
    return out


def main(args: argparse.Namespace) -> int:
    """Generate the dataset and print a JSON summary (exit 2 on bad arguments, before rendering)."""
    problems = _problems(args)
    if problems:
        for p in problems:
            print(f"tactile-force synth: error: {p}", file=sys.stderr)
        return 2
    from ..synthetic.digit import VirtualDigitOptions
    from ..synthetic.generate import DatasetOptions, generate_dataset
    from ..synthetic.indenters import INDENTERS, get_indenter, paper_indenter_names
    from ..synthetic.sampling import ForceDistribution

    if args.indenters == "paper":
        names = tuple(paper_indenter_names())
    elif args.indenters == "all":
        names = tuple(INDENTERS)
    else:
        names = tuple(n.strip() for n in args.indenters.split(",") if n.strip())
        try:
            for n in names:
                get_indenter(n)
        except ValueError as exc:
            print(f"tactile-force synth: error: --indenters: {exc}", file=sys.stderr)
            return 2
    options = DatasetOptions(
        n=args.n, seed=args.seed, indenters=names, frames_per_grasp=args.frames_per_grasp,
        edge_fraction=args.edge_fraction, no_contact_fraction=args.no_contact_fraction,
        forces=ForceDistribution(below_fraction=args.below_fraction, above_fraction=args.above_fraction),
        digit=VirtualDigitOptions(background=args.background, normal_to_rgb_mlp=args.normal_to_rgb_mlp),
        progress=not args.no_progress,
    )
    from ..files.atomic import staged_folder

    # claimed and judged before rendering (free space for n samples included); interrupted: no
    # half dataset, no image without its label
    with staged_folder(args.out, "synth", force=args.force, inputs=_inputs(args),
                       expected_bytes=args.n * SAMPLE_BYTES_MIN) as tmp:
        summary = generate_dataset(tmp, options)
    summary.root = Path(args.out)
    print(json.dumps(summary.as_dict(), indent=1))
    return 0
