"""`mlct render`: draw a motion file as a GIF, MP4 or PNG filmstrip."""

from __future__ import annotations

import argparse
from pathlib import Path

from mlct.cli.parser import Commands


def run(args: argparse.Namespace) -> int:
    from mlct.data.layout import dataset_caption
    from mlct.motion.render import render_file

    # the title: --caption, else the dataset's first caption of the file (DIR/texts/NAME.txt)
    caption = args.caption if args.caption is not None else dataset_caption(args.file)
    out = render_file(args.file, args.out, skeleton=args.skeleton, caption=caption,
                      fps=args.fps)
    print(out)
    return 0


def add_parser(commands: Commands) -> None:
    render = commands.add_parser("render", help="draw a motion file as GIF, MP4 or PNG filmstrip")
    render.add_argument("file", type=Path, help="features (T x 263/251) or joints (T x J x 3) .npy")
    render.add_argument("--out", required=True, type=Path, help="OUT.gif, OUT.mp4 or OUT.png")
    render.add_argument("--skeleton", default=None, help="humanml3d or kit (default: from shape)")
    render.add_argument("--caption", default=None, help="title (default: from the dataset texts)")
    render.add_argument("--fps", type=float, default=None, help="default: the skeleton's fps")
    render.set_defaults(func=run)
