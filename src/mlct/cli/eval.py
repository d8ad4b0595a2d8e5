"""`mlct eval` and `mlct import-evaluator`: the standard metrics, and the judge they need."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Callable

from mlct.cli.parser import Commands


def run_eval(args: argparse.Namespace) -> int:
    import shlex

    from mlct.eval.protocol import ProtocolConfig
    from mlct.eval.report import results_table, write_report
    from mlct.eval.run import run_evaluation
    from mlct.io import check_writable_dir

    config = ProtocolConfig(reps=args.reps, seed=args.seed, batch_size=args.batch_size,
                            diversity_times=args.diversity_times, mm=args.mm,
                            aits_runs=args.aits_runs)
    check_writable_dir(args.out)  # before any work

    def log(message: str) -> None:
        print(message, file=sys.stderr, flush=True)

    report = run_evaluation(args.model, args.data, args.evaluator, nfe=args.nfe,
                            ddim_steps=args.ddim_steps, guidance=args.guidance,
                            split=args.split, config=config, device=args.device,
                            log=None if args.quiet else log,
                            command=shlex.join(["mlct", *args.argv]),
                            classifier_dir=args.classifier, dtype=args.dtype)
    written = write_report(args.out, report)
    print(results_table(report))
    if not args.quiet:
        log("wrote " + ", ".join(str(path) for path in written))
    return 0


def run_import_evaluator(args: argparse.Namespace) -> int:
    from mlct.eval.judge.evaluator_dir import import_official_evaluator

    out = import_official_evaluator(args.checkpoint, args.mean, args.std, args.glove, args.out,
                                    skeleton=args.skeleton, overwrite=args.overwrite)
    print(f"evaluator directory: {out}")
    return 0


def _number_list(kind: type, example: str) -> Callable[[str], list]:
    """An argparse type for comma-separated numbers of `kind` ("1,3,5")."""
    def parse(text: str) -> list:
        try:
            return [kind(item) for item in text.split(",") if item.strip()]
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {example}, got {text!r}") from None
    return parse


_int_list = _number_list(int, "integers like 1,3,5")
_float_list = _number_list(float, "numbers like 0,1,2.5")


def add_parser(commands: Commands) -> None:
    imported = commands.add_parser("import-evaluator", help="make an evaluator directory from "
                                   "Guo et al.'s official files (weights unchanged)")
    imported.add_argument("--checkpoint", required=True, type=Path,
                          help="text_mot_match/model/finest.tar (or its directory)")
    imported.add_argument("--mean", required=True, type=Path,
                          help="the evaluator's mean.npy (Comp_v6_KLD01/meta/mean.npy)")
    imported.add_argument("--std", required=True, type=Path, help="the evaluator's std.npy")
    imported.add_argument("--glove", required=True, type=Path,
                          help="GloVe directory: our_vab_data.npy, _words.pkl, _idx.pkl")
    imported.add_argument("--out", required=True, type=Path, help="evaluator directory to write")
    imported.add_argument("--skeleton", default=None, help="default: from the feature width")
    imported.add_argument("--overwrite", action="store_true")
    imported.set_defaults(func=run_import_evaluator)

    evaluate = commands.add_parser("eval", help="the standard metrics of models on a test split")
    evaluate.add_argument("--model", required=True, type=Path, action="append",
                          help="model directory (repeat for several)")
    evaluate.add_argument("--data", required=True, type=Path, help="dataset directory")
    evaluate.add_argument("--evaluator", required=True, type=Path,
                          help="evaluator directory (`mlct train evaluator`)")
    evaluate.add_argument("--out", required=True, type=Path, help="report directory")
    evaluate.add_argument("--nfe", type=_int_list, default=None,
                          help="consistency models' steps, e.g. 1,3,5,10 (default: the model's)")
    evaluate.add_argument("--ddim-steps", type=_int_list, default=None,
                          help="DDIM models' steps = their NFE (default: the model's, 50)")
    evaluate.add_argument("--guidance", type=_float_list, default=None,
                          help="DDIM models' CFG scales, e.g. 0,1,2 (default: the model's); "
                          "a consistency model's w is fixed at training")
    evaluate.add_argument("--reps", type=int, default=20, help="replications (default 20)")
    evaluate.add_argument("--mm", action="store_true",
                          help="also MultiModality (100 texts x 30 generations a replication)")
    evaluate.add_argument("--classifier", type=Path, default=None,
                          help="action classifier (mlct train classifier): adds semantic "
                               "accuracy, per class too")
    evaluate.add_argument("--split", default="test")
    evaluate.add_argument("--batch-size", type=int, default=32,
                          help="R-precision group and generation batch (default 32)")
    evaluate.add_argument("--seed", type=int, default=0, help="replication r uses seed + r")
    evaluate.add_argument("--diversity-times", type=int, default=None,
                          help="diversity pairs (default 300, fewer on a small split)")
    evaluate.add_argument("--aits-runs", type=int, default=10,
                          help="timed batch-1 runs per configuration (0: no AITS)")
    evaluate.add_argument("--device", default=None, help="cpu or cuda (default: cuda if "
                          "available)")
    evaluate.add_argument("--dtype", choices=["float32", "bfloat16"], default="float32",
                          help="the models' matrix-product precision (default float32)")
    evaluate.add_argument("--quiet", action="store_true", help="no progress on stderr")
    evaluate.set_defaults(func=run_eval)
