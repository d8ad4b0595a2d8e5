"""The `mlct` command: parse, call the library, print. No logic lives here."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any, Callable

from mlct.errors import MlctError


class _Parser(argparse.ArgumentParser):
    """argparse that reports usage errors in one line (exit 2), without the usage dump."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"mlct: error: {message}\n")


MAX_MOTIONS = 100_000  # motions one `mlct generate` makes (files and names are listed first)


def _cmd_data_synth(args: argparse.Namespace) -> int:
    from mlct.data.synth.build import synthesize_dataset

    summary = synthesize_dataset(args.out, num=args.num, seed=args.seed, skeleton=args.skeleton,
                                 workers=args.workers, progress=not args.quiet,
                                 overwrite=args.overwrite)
    print(f"wrote {summary['motions']} motions ({summary['frames']} frames, "
          f"skating ratio {summary['skating_ratio']:.4f}) to {args.out}")
    return 0


def _cmd_data_stats(args: argparse.Namespace) -> int:
    from mlct.data.stats import dataset_statistics, format_statistics

    stats = dataset_statistics(args.dir, skeleton=args.skeleton, write_mean_std=not args.no_write)
    print(format_statistics(stats))
    return 0


def _cmd_data_check(args: argparse.Namespace) -> int:
    from mlct.data.check import check_dataset

    problems = check_dataset(args.dir, skeleton=args.skeleton)
    for problem in problems:
        print(problem)
    if problems:
        print(f"{len(problems)} problem(s) found in {args.dir}")
        return 1
    print(f"{args.dir}: no problems found")
    return 0


def _cmd_data_import(args: argparse.Namespace) -> int:
    from mlct.data.importer import format_summary, import_dataset, parse_split

    summary = import_dataset(args.out, args.captions, joints_dir=args.joints, bvh_dir=args.bvh,
                             skeleton=args.skeleton, joint_map=args.joint_map, scale=args.scale,
                             fps=args.fps, split=parse_split(args.split), seed=args.seed,
                             skip_uncaptioned=args.skip_uncaptioned, overwrite=args.overwrite,
                             progress=not args.quiet)
    print(format_summary(summary))
    return 0


def _cmd_render(args: argparse.Namespace) -> int:
    from mlct.data.layout import dataset_caption
    from mlct.motion.render import render_file

    # the title: --caption, else the dataset's first caption of the file (DIR/texts/NAME.txt)
    caption = args.caption if args.caption is not None else dataset_caption(args.file)
    out = render_file(args.file, args.out, skeleton=args.skeleton, caption=caption,
                      fps=args.fps)
    print(out)
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
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


def _cmd_train(args: argparse.Namespace) -> int:
    from mlct.config import load_config
    from mlct.train.loop import train

    if args.resume and args.config is not None:
        raise MlctError("--resume continues the run's saved config; drop --config")
    if args.init is not None and args.config is not None:
        raise MlctError("--init takes the model's own config; drop --config (key=value "
                        "overrides still apply)")
    if args.init == "bundled":
        from mlct.generate.pipeline import bundled_model_dir

        args.init = bundled_model_dir()
    saved = args.resume or args.init is not None  # the config comes from the run or the model
    config = None if saved else load_config(args.config or "small", args.overrides)
    summary = train(args.stage, args.data, args.out, config=config,
                    overrides=args.overrides if saved else [], resume=args.resume,
                    ae_path=args.ae, device=args.device, progress=not args.quiet,
                    init=args.init)
    if summary.get("is_main", True):
        last = ", ".join(f"{k} {v:.4g}" for k, v in summary["last"].items())
        print(f"{args.stage}: step {summary['step']}, {last}; "
              f"{summary['samples_per_s']:.1f} samples/s; {summary['checkpoint']}")
    return 0


def _cmd_train_evaluator(args: argparse.Namespace) -> int:
    from mlct.eval.judge.train_evaluator import train_evaluator

    from mlct.eval.judge.evaluator import EVALUATOR_SIZES
    from mlct.eval.judge.train_evaluator import EvaluatorTrainConfig

    config = EvaluatorTrainConfig(sizes=EVALUATOR_SIZES[args.sizes])
    summary = train_evaluator(args.data, args.out, glove_dir=args.glove,
                              steps_decomp=args.steps_decomp, steps_match=args.steps_match,
                              batch_size=args.batch_size, seed=args.seed, device=args.device,
                              progress=not args.quiet, config=config, overwrite=args.overwrite)
    print(f"evaluator: {summary['vocabulary']} word vectors ({summary['vocabulary_size']}), "
          f"{summary['train_items']} train items, best step {summary['best_step']}; "
          f"{summary['path']}")
    return 0


def _cmd_train_classifier(args: argparse.Namespace) -> int:
    from mlct.eval.judge.action_classifier import train_action_classifier

    summary = train_action_classifier(args.data, args.out, steps=args.steps,
                                      batch_size=args.batch_size, seed=args.seed,
                                      device=args.device,
                                      progress=not args.quiet, overwrite=args.overwrite)
    test = summary["accuracy"]["test"]
    print(f"action classifier: {len(summary['classes'])} classes; test exact-set accuracy "
          f"{test['exact_set_accuracy']:.3f}, mean recall {test['mean_recall']:.3f}; {args.out}")
    return 0


def _cmd_import_evaluator(args: argparse.Namespace) -> int:
    from mlct.eval.judge.evaluator_dir import import_official_evaluator

    out = import_official_evaluator(args.checkpoint, args.mean, args.std, args.glove, args.out,
                                    skeleton=args.skeleton, overwrite=args.overwrite)
    print(f"evaluator directory: {out}")
    return 0


def _trainer_options(parser: argparse.ArgumentParser, what: str, batch_size: int) -> None:
    """The options the evaluator and the action classifier trainers share."""
    parser.add_argument("--data", required=True, type=Path, help="dataset directory")
    parser.add_argument("--out", required=True, type=Path, help=f"{what} directory to write")
    parser.add_argument("--batch-size", type=int, default=batch_size)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--device", default=None,
                        help="cpu or cuda (default: cuda if available)")
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace an existing {what} directory")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


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


def _port(text: str) -> int:
    # Checked here: uvicorn would take 99999 and fail with an OverflowError once the model loaded.
    try:
        port = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid int value: {text!r}") from None
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"a TCP port is 0..65535, got {port}")
    return port


def _cmd_eval(args: argparse.Namespace) -> int:
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


def _cmd_export(args: argparse.Namespace) -> int:
    from mlct.train.export import export_run

    print(export_run(args.run, args.out, stage=args.stage, half=args.half, onnx=args.onnx))
    return 0


def _cmd_convert(args: argparse.Namespace) -> int:
    from mlct.generate.onnx_bundle import convert_to_onnx
    from mlct.generate.pipeline import bundled_model_dir

    if not args.onnx:
        raise MlctError("say what to convert the model to: --onnx (ONNX graphs for "
                        "--backend onnx)")
    bundled = str(args.model) == "bundled"
    print(convert_to_onnx(bundled_model_dir() if bundled else args.model, args.out,
                          read_only=bundled))
    return 0


def _cmd_serve(args: argparse.Namespace) -> int:
    from mlct.serve import run_server

    run_server(args.model, host=args.host, port=args.port, device=args.device, token=args.token,
               backend=args.backend)
    return 0


def _cmd_generate(args: argparse.Namespace) -> int:
    import mlct
    from mlct.generate import files as generate_files
    from mlct.generate.prompts import clean_prompt, read_prompts

    if args.prompts is not None and args.text:
        raise MlctError("give prompts on the command line or with --prompts FILE, not both")
    if args.num < 1:
        raise MlctError(f"--num must be at least 1, got {args.num}")
    if args.num > MAX_MOTIONS:  # checked before a name per motion is built (10^9 ran out of memory)
        raise MlctError(f"--num {args.num} is more than the {MAX_MOTIONS:,} motions one command "
                        f"makes; split the work over several commands")
    prompts = (read_prompts(args.prompts) if args.prompts is not None
               else [clean_prompt(t) for t in args.text])
    if len(prompts) * args.num > MAX_MOTIONS:
        raise MlctError(f"{len(prompts)} prompts x --num {args.num} make more than the "
                        f"{MAX_MOTIONS:,} motions one command makes")
    if not prompts:
        raise MlctError("no prompt: mlct generate \"a person walks forward\" --out walk.gif")
    long = args.prompts is None and len(prompts) > 1
    if long and args.num > 1:
        raise MlctError("--num makes variations of one prompt; several prompts make one long "
                        "motion")
    request = generate_files.Request(prompts, args.seconds, args.length, args.num, args.nfe,
                                     args.seed, long, split_actions=not args.whole_prompt)
    names = ["_".join(prompts)] if long else [p for p in prompts for _ in range(args.num)]
    paths = generate_files.output_paths(names, args.out, args.out_dir, args.format)
    def load() -> Any:
        # A status line while the model and the text encoder load (a second or more cold),
        # on a terminal only: scripts and pipes keep a clean stderr.
        status = not args.quiet and sys.stderr.isatty()
        if status:
            print("mlct: loading the model and the text encoder ...", end="\r", file=sys.stderr,
                  flush=True)
        generator = mlct.load(args.model, device=args.device, dtype=args.dtype,
                              backend=args.backend)
        generator.text_encoder  # noqa: B018 - loads it now, under the status line
        if status:
            print(" " * 50, end="\r", file=sys.stderr, flush=True)
        return generator

    written = generate_files.run(load, request, paths, features=args.features,
                                 progress=not args.quiet)
    for path in written:
        print(path)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="mlct", description="Real-time text-to-motion generation (MLCT).")
    parser.add_argument("--version", action="version", version=_version())
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    data = commands.add_parser("data", help="make, check and describe datasets")
    data_commands = data.add_subparsers(dest="data_command", required=True, parser_class=_Parser)

    synth = data_commands.add_parser("synth", help="write a procedural text-motion benchmark")
    synth.add_argument("--out", required=True, type=Path, help="dataset directory to create")
    synth.add_argument("--num", type=int, default=1000, help="number of motions (default 1000)")
    synth.add_argument("--seed", type=int, default=0)
    synth.add_argument("--skeleton", default="humanml3d", choices=["humanml3d", "kit"])
    synth.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    synth.add_argument("--overwrite", action="store_true", help="replace an existing dataset")
    synth.add_argument("--quiet", action="store_true", help="no progress bar")
    synth.set_defaults(func=_cmd_data_synth)

    stats = data_commands.add_parser("stats", help="write Mean/Std and print dataset statistics")
    stats.add_argument("dir", type=Path)
    stats.add_argument("--skeleton", default=None, help="humanml3d or kit (default: from width)")
    stats.add_argument("--no-write", action="store_true", help="print only; keep Mean/Std")
    stats.set_defaults(func=_cmd_data_stats)

    check = data_commands.add_parser("check", help="validate a dataset; exit 1 if problems")
    check.add_argument("dir", type=Path)
    check.add_argument("--skeleton", default=None, help="humanml3d or kit (default: from width)")
    check.set_defaults(func=_cmd_data_check)

    imported = data_commands.add_parser(
        "import", help="turn your own motion capture (joints .npy or BVH) and captions into a "
                       "dataset in the standard layout (docs/custom_data.md)")
    source = imported.add_mutually_exclusive_group(required=True)
    source.add_argument("--joints", type=Path, help="directory of (T, J, 3) .npy joints, y up")
    source.add_argument("--bvh", type=Path, help="directory of .bvh files")
    imported.add_argument("--captions", required=True, type=Path,
                          help="CSV (name,caption) or JSONL ({name, caption|captions})")
    imported.add_argument("--skeleton", default="humanml3d", choices=["humanml3d", "kit"])
    imported.add_argument("--out", required=True, type=Path, help="dataset directory to create")
    imported.add_argument("--joint-map", type=Path, default=None,
                          help="JSON {BVH joint: skeleton joint} (default: same names)")
    imported.add_argument("--scale", type=float, default=None,
                          help="factor to the skeleton's units, m or mm (default: guessed)")
    imported.add_argument("--fps", type=float, default=None,
                          help="input frame rate (default: BVH Frame Time; skeleton fps for .npy)")
    imported.add_argument("--split", default="0.8,0.1,0.1", help="train,val,test fractions")
    imported.add_argument("--seed", type=int, default=0, help="seed of the split shuffle")
    imported.add_argument("--skip-uncaptioned", action="store_true",
                          help="skip motion files without a caption instead of stopping")
    imported.add_argument("--overwrite", action="store_true", help="replace an existing dataset")
    imported.add_argument("--quiet", action="store_true", help="no progress bar")
    imported.set_defaults(func=_cmd_data_import)

    demo = commands.add_parser("demo", help="make a small procedural dataset, render one motion")
    demo.add_argument("--out", type=Path, default=Path("mlct-demo"), help="default ./mlct-demo")
    demo.add_argument("--num", type=int, default=8, help="motions to make (default 8)")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--index", type=int, default=0, help="which motion to render")
    demo.set_defaults(func=_cmd_demo)

    train = commands.add_parser("train", help="train a stage: ae, then cm (or diffusion); "
                                "or the evaluator")
    stages = train.add_subparsers(dest="stage", required=True, parser_class=_Parser,
                                  metavar="{ae,cm,diffusion,evaluator,classifier}")
    for stage, help_text in (("ae", "stage 1: the motion autoencoder"),
                             ("cm", "stage 2: latent consistency training (MLCT)"),
                             ("diffusion", "stage 2 baseline: latent diffusion (DDIM + CFG)")):
        parser_ = stages.add_parser(stage, help=help_text)
        parser_.add_argument("--data", required=True, type=Path, help="dataset directory")
        parser_.add_argument("--out", required=True, type=Path,
                             help="run directory (all stages)")
        parser_.add_argument("--config", default=None, help="preset (humanml3d, kit, small, "
                             "tiny) or YAML file; default small")
        parser_.add_argument("overrides", nargs="*", metavar="key=value",
                             help="config overrides, e.g. train.cm.max_steps=2000 "
                             "consistency.guidance=2")
        parser_.add_argument("--resume", action="store_true",
                             help="continue from the latest checkpoint")
        parser_.add_argument("--ae", default=None, help="AE checkpoint for cm/diffusion "
                             "(default: RUN/ae's latest)")
        parser_.add_argument("--init", default=None, metavar="MODEL_DIR",
                             help="fine-tune: start from a model's config, normalization and "
                             "weights; 'bundled' = the model that ships with mlct")
        parser_.add_argument("--device", default=None,
                             help="cpu or cuda (default: cuda if available)")
        parser_.add_argument("--quiet", action="store_true", help="no progress bar")
        parser_.set_defaults(func=_cmd_train)

    evaluator = stages.add_parser("evaluator", help="the text-motion matching evaluator of "
                                  "the standard metrics (Guo et al. 2022)")
    _trainer_options(evaluator, "evaluator", batch_size=32)
    evaluator.add_argument("--glove", default=None, type=Path,
                           help="GloVe directory (our_vab_*); default: learn word vectors")
    evaluator.add_argument("--steps-decomp", type=int, default=5000,
                           help="movement autoencoder steps (default 5000)")
    evaluator.add_argument("--steps-match", type=int, default=15000,
                           help="text-motion co-embedding steps (default 15000)")
    evaluator.add_argument("--sizes", choices=["official", "compact"], default="official",
                           help="network widths: the official evaluator's (default) or compact "
                           "ones, about 10x faster to train on a CPU")
    evaluator.set_defaults(func=_cmd_train_evaluator)

    classifier = stages.add_parser("classifier", help="the action classifier of the semantic "
                                   "accuracy (procedural benchmarks: labels.jsonl)")
    _trainer_options(classifier, "classifier", batch_size=64)
    classifier.add_argument("--steps", type=int, default=1500, help="default 1500")
    classifier.set_defaults(func=_cmd_train_classifier)

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
    imported.set_defaults(func=_cmd_import_evaluator)

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
    evaluate.set_defaults(func=_cmd_eval)

    export = commands.add_parser("export", help="write an inference bundle from a training run")
    export.add_argument("run", type=Path)
    export.add_argument("--out", required=True, type=Path, help="model directory to write")
    export.add_argument("--stage", default=None, choices=["cm", "diffusion"],
                        help="which stage-2 model (default cm)")
    export.add_argument("--half", action="store_true", help="store weights in float16")
    export.add_argument("--onnx", action="store_true",
                        help="also write the networks as ONNX graphs (for --backend onnx)")
    export.set_defaults(func=_cmd_export)

    convert = commands.add_parser("convert", help="add ONNX graphs to a model directory "
                                  "(for --backend onnx)")
    convert.add_argument("model", type=Path,
                         help="model directory, or 'bundled' (the model inside mlct)")
    convert.add_argument("--onnx", action="store_true",
                         help="write the text encoder, denoiser and decoder as ONNX graphs")
    convert.add_argument("--out", type=Path, default=None,
                         help="copy the model here with its graphs (default: MODEL/onnx/; "
                         "needed for 'bundled')")
    convert.set_defaults(func=_cmd_convert)

    serve = commands.add_parser("serve", help="the JSON API and the web page (real-time "
                                "generation in the browser)")
    serve.add_argument("--model", type=Path, default=None,
                       help="model directory (default: the bundled model)")
    serve.add_argument("--host", default="127.0.0.1", help="default 127.0.0.1 (this machine)")
    serve.add_argument("--port", type=_port, default=8000, help="default 8000")
    serve.add_argument("--device", default=None, help="cpu or cuda (default: cuda if available)")
    serve.add_argument("--backend", default="torch",
                       help="torch (default) or onnx: ONNX Runtime on the CPU, after "
                       "`mlct convert MODEL --onnx`")
    serve.add_argument("--token", default=None,
                       help="require 'Authorization: Bearer TOKEN' on POST /generate "
                       "(default: $MLCT_TOKEN; the page takes it as #token=TOKEN)")
    serve.set_defaults(func=_cmd_serve)

    generate = commands.add_parser(
        "generate", help="text to motion: GIF, MP4, PNG filmstrip, NPY, JSON or BVH",
        description="One prompt: one motion (--num for variations). Several prompts with one "
                    "duration each: one continuous long motion doing them in order. --prompts "
                    "FILE: one motion per line.")
    generate.add_argument("text", nargs="*", help="what the person does")
    generate.add_argument("--prompts", type=Path, default=None,
                          help="a UTF-8 file, one prompt per line (batched)")
    generate.add_argument("--model", type=Path, default=None,
                          help="model directory (default: the bundled model)")
    length = generate.add_mutually_exclusive_group()
    length.add_argument("--seconds", type=float, nargs="+", default=None,
                        help="duration; one per prompt for a long motion (default 5)")
    length.add_argument("--length", type=int, nargs="+", default=None, help="frames")
    generate.add_argument("--nfe", type=int, default=None, help="sampling steps (default 5)")
    generate.add_argument("--seed", type=int, default=None,
                          help="motion i gets seed + i (default: random)")
    generate.add_argument("--num", type=int, default=1, help="variations per prompt (default 1)")
    generate.add_argument("--device", default=None)
    generate.add_argument("--dtype", default="float32", choices=["float32", "bfloat16"],
                          help="precision of the networks' products (docs/performance.md)")
    generate.add_argument("--backend", default="torch",
                          help="torch (default) or onnx: ONNX Runtime on the CPU, after "
                          "`mlct convert MODEL --onnx`")
    generate.add_argument("--whole-prompt", action="store_true",
                          help="give the model a prompt that names actions in sequence ('walks, "
                               "then waves') as one text, instead of one part per action, chained")
    generate.add_argument("--features", action="store_true",
                          help=".npy holds the features (T x 263) instead of joints (T x J x 3)")
    where = generate.add_mutually_exclusive_group()
    where.add_argument("--out", type=Path, default=None,
                       help="FILE.gif, .mp4, .png, .npy, .json or .bvh (several: FILE_000.gif, ...)")
    where.add_argument("--out-dir", type=Path, default=None,
                       help="directory; files named after the prompts")
    generate.add_argument("--format", default=None,
                          help="with --out-dir: gif (default), mp4, png, npy, json or bvh")
    generate.add_argument("--quiet", action="store_true", help="no progress bar")
    generate.set_defaults(func=_cmd_generate)

    render = commands.add_parser("render", help="draw a motion file as GIF, MP4 or PNG filmstrip")
    render.add_argument("file", type=Path, help="features (T x 263/251) or joints (T x J x 3) .npy")
    render.add_argument("--out", required=True, type=Path, help="OUT.gif, OUT.mp4 or OUT.png")
    render.add_argument("--skeleton", default=None, help="humanml3d or kit (default: from shape)")
    render.add_argument("--caption", default=None, help="title (default: from the dataset texts)")
    render.add_argument("--fps", type=float, default=None, help="default: the skeleton's fps")
    render.set_defaults(func=_cmd_render)
    return parser


def _version() -> str:
    from mlct import __version__

    return f"mlct {__version__}"


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    # key=value overrides may come anywhere after `mlct train STAGE` (argparse would only take
    # them right after the stage); anything else left over is an error, as parse_args makes it.
    overrides = [item for item in extra if "=" in item and not item.startswith("-")]
    unknown = [item for item in extra if item not in overrides]
    if overrides and not hasattr(args, "overrides"):  # only `mlct train ae|cm|diffusion`
        unknown = extra
    if unknown:
        parser.error(f"unrecognized arguments: {' '.join(unknown)}")
    if overrides:
        args.overrides = list(args.overrides) + overrides
    args.argv = list(sys.argv[1:] if argv is None else argv)  # reports record the command
    try:
        return args.func(args)
    except MlctError as error:
        print(f"mlct: error: {error}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # `mlct ... | head`: the reader left; that is not an error. Point stdout at devnull so
        # that the interpreter's final flush does not raise again.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as error:
        # A file the user named cannot be read or written: say which, in one line.
        where = f": {error.filename}" if error.filename else ""
        print(f"mlct: error: {error.strerror or error}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mlct: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
