"""``tactile-force synth``: generate a synthetic labelled DIGIT dataset (authors' layout).

    tactile-force synth --out data/synth --n 5000 --seed 0
"""

from __future__ import annotations

import argparse
import json
import sys


def configure(parser: argparse.ArgumentParser) -> None:
    """Arguments of the synth command."""
    parser.add_argument("--out", required=True, help="output folder (created; must not hold images/ yet)")
    parser.add_argument("--n", type=int, default=1000, help="number of samples (default 1000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (same seed -> same files)")
    parser.add_argument("--indenters", default="paper",
                        help="'paper' (the 18 paper-like indenters), 'all', or comma-separated names")
    parser.add_argument("--frames-per-grasp", type=int, default=8, help="samples sharing one pose (default 8)")
    parser.add_argument("--edge-fraction", type=float, default=0.15, help="share of contacts near a border")
    parser.add_argument("--below-fraction", type=float, default=0.0, help="share of samples in 0-1 N")
    parser.add_argument("--above-fraction", type=float, default=0.0, help="share of samples in 15-20 N")
    parser.add_argument("--no-contact-fraction", type=float, default=0.0, help="share of 0 N frames")
    parser.add_argument("--background", default=None, help="no-contact DIGIT frame to render on (default: shipped)")
    parser.add_argument("--normal-to-rgb-mlp", default=None,
                        help="FOTS normal->colour MLP .npz to shade with instead of the analytic LED model")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    """Generate the dataset and print a JSON summary."""
    from .digit import VirtualDigitOptions
    from .generate import DatasetOptions, generate_dataset
    from .indenters import INDENTERS, get_indenter, paper_indenter_names
    from .sampling import ForceDistribution

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
    summary = generate_dataset(args.out, options)
    print(json.dumps(summary.as_dict(), indent=1))
    return 0
