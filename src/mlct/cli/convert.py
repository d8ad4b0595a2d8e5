"""`mlct convert MODEL|bundled --onnx`: add ONNX graphs to a model directory;
`--decoder-from RUN --out DIR`: a copy of the model with another decoder (train/export.py)."""

from __future__ import annotations

import argparse
from pathlib import Path

from mlct.cli.parser import Commands
from mlct.errors import MlctError


def run(args: argparse.Namespace) -> int:
    from mlct.generate.backends.onnx.convert import convert_to_onnx
    from mlct.generate.bundle import bundled_model_dir

    if not args.onnx and args.decoder_from is None:
        raise MlctError("say what to convert the model to: --onnx (ONNX graphs for "
                        "--backend onnx) or --decoder-from RUN (another decoder)")
    if args.int8 and not args.onnx:  # (else the copy would be made and --int8 do nothing)
        raise MlctError("--int8 quantizes the ONNX graphs: give --onnx too")
    bundled = str(args.model) == "bundled"
    model = bundled_model_dir() if bundled else args.model
    if args.decoder_from is not None:
        from mlct.train.export import bundle_with_decoder

        if args.out is None:
            raise MlctError("--decoder-from writes a new model: give it --out DIR")
        model = bundle_with_decoder(model, args.decoder_from, args.out)
        if not args.onnx:
            print(model)
            return 0
        bundled, args.out = False, None  # the graphs go into the new copy
    print(convert_to_onnx(model, args.out, read_only=bundled, int8=args.int8))
    return 0


def add_parser(commands: Commands) -> None:
    convert = commands.add_parser("convert", help="add ONNX graphs to a model directory "
                                  "(for --backend onnx)")
    convert.add_argument("model", type=Path,
                         help="model directory, or 'bundled' (the model inside mlct)")
    convert.add_argument("--onnx", action="store_true",
                         help="write the text encoder, denoiser and decoder as ONNX graphs")
    convert.add_argument("--out", type=Path, default=None,
                         help="copy the model here with its graphs (default: MODEL/onnx/; "
                         "needed for 'bundled')")
    convert.add_argument("--int8", action="store_true",
                         help="quantize the denoiser's matrix products to int8, a scale per 32 "
                         "weights (~1.4x faster on a CPU; joints 1-8 mm from float32's on "
                         "average: docs/performance.md)")
    convert.add_argument("--decoder-from", type=Path, default=None, metavar="RUN",
                         help="copy the model to --out with the decoder of RUN, an autoencoder "
                         "trained on its frozen encoder (train ae --init MODEL "
                         "ae.freeze_encoder=true)")
    convert.set_defaults(func=run)
