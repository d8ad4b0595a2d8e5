"""`mlct demo`: a small procedural dataset, and one of its motions drawn as a GIF."""

from __future__ import annotations

import argparse
from pathlib import Path

from mlct.cli.parser import Commands
from mlct.errors import MlctError


def run(args: argparse.Namespace) -> int:
    from mlct.data.layout import DatasetLayout, dataset_caption
    from mlct.data.synth.build import synthesize_dataset
    from mlct.motion.render import render_file

    if args.num < 1:
        raise MlctError(f"--num must be at least 1, got {args.num}")
    if not 0 <= args.index < args.num:  # before any work: nothing is written for a bad index
        raise MlctError(f"--index {args.index} is not one of the {args.num} motions made "
                        f"(0..{args.num - 1})")
    data = args.out / "data"
    synthesize_dataset(data, num=args.num, seed=args.seed, progress=False, overwrite=True)
    name = f"{args.index:06d}"
    motion = DatasetLayout(data).features_path(name)
    caption = dataset_caption(motion)
    gif = render_file(motion, args.out / f"{name}.gif", caption=caption)
    print(f"{caption}")
    print(gif)
    return 0


def add_parser(commands: Commands) -> None:
    demo = commands.add_parser("demo", help="make a small procedural dataset, render one motion")
    demo.add_argument("--out", type=Path, default=Path("mlct-demo"), help="default ./mlct-demo")
    demo.add_argument("--num", type=int, default=8, help="motions to make (default 8)")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--index", type=int, default=0, help="which motion to render")
    demo.set_defaults(func=run)
