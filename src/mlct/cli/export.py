"""`mlct export`: a training run -> an inference bundle."""

from __future__ import annotations

import argparse
from pathlib import Path

from mlct.cli.parser import Commands


def run(args: argparse.Namespace) -> int:
    from mlct.train.export import export_run

    print(export_run(args.run, args.out, stage=args.stage, half=args.half, onnx=args.onnx,
                     decoder_from=args.decoder_from))
    return 0


def add_parser(commands: Commands) -> None:
    export = commands.add_parser("export", help="write an inference bundle from a training run")
    export.add_argument("run", type=Path)
    export.add_argument("--out", required=True, type=Path, help="model directory to write")
    export.add_argument("--stage", default=None, choices=["cm", "diffusion"],
                        help="which stage-2 model (default cm)")
    export.add_argument("--half", action="store_true", help="store weights in float16")
    export.add_argument("--decoder-from", type=Path, default=None, metavar="AE_RUN",
                        help="take the decoder from this autoencoder run, trained with the "
                        "encoder frozen (ae.freeze_encoder=true)")
    export.add_argument("--onnx", action="store_true",
                        help="also write the networks as ONNX graphs (for --backend onnx)")
    export.set_defaults(func=run)
