"""`mlct train ae|cm|diffusion|durations|critic|anchors|evaluator|classifier`: the model's stages,
and the judges."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from mlct.cli.parser import Commands, Parser
from mlct.errors import MlctError


def run_stage(args: argparse.Namespace) -> int:
    from mlct.config import load_config
    from mlct.train.loop import train

    if args.resume and args.config is not None:
        raise MlctError("--resume continues the run's saved config; drop --config")
    if args.init is not None and args.config is not None:
        raise MlctError("--init takes the model's own config; drop --config (key=value "
                        "overrides still apply)")
    if args.init == "bundled":
        from mlct.generate.bundle import bundled_model_dir

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


def run_evaluator(args: argparse.Namespace) -> int:
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


def run_classifier(args: argparse.Namespace) -> int:
    from mlct.eval.judge.action_classifier import train_action_classifier

    summary = train_action_classifier(args.data, args.out, steps=args.steps,
                                      batch_size=args.batch_size, seed=args.seed,
                                      device=args.device,
                                      progress=not args.quiet, overwrite=args.overwrite)
    test = summary["accuracy"]["test"]
    print(f"action classifier: {len(summary['classes'])} classes; test exact-set accuracy "
          f"{test['exact_set_accuracy']:.3f}, mean recall {test['mean_recall']:.3f}; {args.out}")
    return 0


def run_durations(args: argparse.Namespace) -> int:
    """Fit the part-duration model (train/durations.py) on one split of a labelled dataset, in
    the model's text space, and write it beside the model's weights."""
    import numpy as np

    import mlct
    from mlct.data.layout import DatasetLayout
    from mlct.eval.judge.action_classifier import read_labels
    from mlct.generate.compose.actions import split_actions
    from mlct.generate.compose.durations import describe
    from mlct.generate.compose.lengths import MIN_PART_SECONDS
    from mlct.generate.bundle import bundled_model_dir
    from mlct.train.durations import (CUT_SHIFT, cut_errors, fit_durations, fit_offsets,
                                      memoized_embedder, sequence_examples,
                                      single_action_captions, single_action_extra)

    model_dir = bundled_model_dir() if args.model == "bundled" else Path(args.model)
    generator = mlct.load(model_dir, backend="torch")
    layout = DatasetLayout.existing(args.data)
    all_labels = read_labels(args.data)
    labels = {k: v for k, v in all_labels.items() if k in set(layout.read_split(args.split))}
    texts, seconds, groups = single_action_captions(labels)
    sequences = sequence_examples(labels, split_actions)
    parts = [p for e in sequences for p in e.parts]
    part_seconds = [s for e in sequences for s in e.seconds]
    part_groups = [e.motion for e in sequences for _ in e.parts]
    embed = memoized_embedder(generator)

    model = fit_durations(embed(texts + parts), np.concatenate([seconds, part_seconds]),
                          generator.meta["text_encoder"], np.concatenate([groups, part_groups]))
    model = dataclasses.replace(fit_offsets(model, sequences, embed),
                                single_extra=single_action_extra(labels))
    fps = generator.skeleton.fps
    fit = dict(model.fit, single_action_captions=len(texts), sequence_parts=len(parts))
    report = [("fitted", sequences)]
    if args.split != "test" and "test" in layout.splits():
        held = {k: v for k, v in all_labels.items() if k in set(layout.read_split("test"))}
        report.append(("test", sequence_examples(held, split_actions)))
    for name, examples in report:
        if examples:
            errors = np.abs(cut_errors(model, examples, embed, fps, MIN_PART_SECONDS))
            fit[f"cut_error_seconds_{name}"] = {"mean": round(float(errors.mean()), 3),
                                                "p90": round(float(np.percentile(errors, 90)), 3),
                                                "sequences": len(examples)}
    model = dataclasses.replace(model, fit=fit)
    path = model.save(model_dir)
    print(f"durations: {len(texts)} single-action captions and {len(parts)} sequence parts "
          f"({args.split}); held-out median error {100 * fit['held_out_median_error']:.1f} %, "
          f"r2 {fit['held_out_r2']:.3f}; offsets by place "
          + ", ".join(f"{k} {v:+.2f} s" for k, v in model.offsets.items())
          + f", a one-action clip {model.single_extra:.2f} s beyond its action; {path}")
    for name, _ in report:
        if f"cut_error_seconds_{name}" in fit:
            err = fit[f"cut_error_seconds_{name}"]
            print(f"  parts' cuts from the data's, less {CUT_SHIFT:.2f} s ({name} sequences, "
                  f"{err['sequences']}): mean "
                  f"{err['mean']:.2f} s, 90th percentile {err['p90']:.2f} s")
    examples = ["a person walks forward", "a person turns slightly left",
                "a person sits down and stands up", "a person jumps twice"]
    print(describe(model, examples, embed(examples)))
    return 0


def run_critic(args: argparse.Namespace) -> int:
    """Train the best-of-N critic (train/critic.py) and write it beside the model's weights."""
    from mlct.generate.compose.critic import DEFAULT_MARGIN, check_candidates, check_margin
    from mlct.generate.bundle import bundled_model_dir
    from mlct.eval.readouts import evaluate_label
    from mlct.train.critic import train_critic

    model_dir = bundled_model_dir() if args.model == "bundled" else Path(args.model)
    check_candidates(args.candidates)
    margin = DEFAULT_MARGIN if args.margin is None else check_margin(args.margin)
    summary = train_critic(args.data, model_dir, split=args.split, steps=args.steps,
                           seed=args.seed, candidates=args.candidates, samples=args.samples,
                           judge=evaluate_label, log=(lambda _: None) if args.quiet else print,
                           margin=margin)
    held = summary.get("test")
    print(f"critic: {summary['captions']} captions, {summary['steps']} steps, "
          f"{summary['seconds']:.0f} s" + (f"; test label top-1 {held['label_top1']:.3f}, "
                                           f"side vs mirror {held['side_vs_mirror']:.3f}, count vs "
                                           f"recount {held['count_vs_recount']:.3f}"
                                           if held else "") + f"; {model_dir}")
    return 0


def run_anchors(args: argparse.Namespace) -> int:
    """Make the model's text anchors (train/text_anchors.py) and write them beside its weights."""
    from mlct.generate.bundle import bundled_model_dir
    from mlct.train.text_anchors import make_text_anchors

    model_dir = bundled_model_dir() if args.model == "bundled" else Path(args.model)
    make_text_anchors(args.data, model_dir, split=args.split, calibrate=args.calibrate,
                      size=args.size, pull=args.pull, seed=args.seed,
                      agreed_pull=args.agreed_pull)
    return 0


def _beside_model_options(parser: argparse.ArgumentParser, data: str, file: str, split: str
                          ) -> None:
    """--data, --model and --split of the stages that write a file beside a model's weights."""
    parser.add_argument("--data", required=True, type=Path, help=data)
    parser.add_argument("--model", required=True, metavar="MODEL_DIR",
                        help=f"the exported model to add {file} to ('bundled' = the model that "
                        "ships with mlct)")
    parser.add_argument("--split", default="train", help=split)


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


def add_parser(commands: Commands) -> None:
    train = commands.add_parser("train", help="train a stage: ae, then cm (or diffusion); "
                                "or the evaluator")
    stages = train.add_subparsers(dest="stage", required=True, parser_class=Parser,
                                  metavar="{ae,cm,diffusion,durations,critic,anchors,evaluator,"
                                  "classifier}")
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
                             "weights; 'bundled' = the model that ships with mlct; for "
                             "train ae also an autoencoder run (its latest checkpoint)")
        parser_.add_argument("--device", default=None,
                             help="cpu or cuda (default: cuda if available)")
        parser_.add_argument("--quiet", action="store_true", help="no progress bar")
        parser_.set_defaults(func=run_stage)

    durations = stages.add_parser("durations", help="how long each action of a split prompt "
                                  "takes: fitted on a labelled dataset, written beside a model")
    _beside_model_options(durations, "a labelled dataset (labels.jsonl: `mlct data synth`)",
                          "durations.json", "the split to fit on (train)")
    durations.set_defaults(func=run_durations)

    critic = stages.add_parser("critic", help="the text-motion critic of best-of-N sampling: "
                               "trained on a dataset, written beside a model")
    _beside_model_options(critic, "dataset directory (its labels.jsonl, when present, keeps "
                          "same-label motions off each other)", "critic.safetensors",
                          "the split to train on (train)")
    critic.add_argument("--steps", type=int, default=3000)
    critic.add_argument("--seed", type=int, default=0)
    critic.add_argument("--candidates", type=int, default=8,
                        help="the model's default best-of-N (default 8)")
    critic.add_argument("--margin", type=float, default=None,
                        help="the model's default margin: the first candidate within it of "
                        "the critic's best is kept (default: generate/compose/critic.py's "
                        "DEFAULT_MARGIN; 0 = the best)")
    critic.add_argument("--samples", type=int, default=0, metavar="K",
                        help="also rank the model's own K samples of each one-action training "
                        "motion by the benchmark's read-outs (needs labels.jsonl; 0: off)")
    critic.add_argument("--quiet", action="store_true", help="print only the summary")
    critic.set_defaults(func=run_critic)

    anchors = stages.add_parser("anchors", help="the training captions that a prompt worded "
                                "unlike any of them is pulled towards: written beside a model")
    _beside_model_options(anchors, "dataset directory (its labels.jsonl, when present, keeps "
                          "the one-action motions' captions)", "text_anchors.safetensors",
                          "the captions to keep (train)")
    anchors.add_argument("--calibrate", default="val", help="the split whose captions the "
                         "anchors must leave alone (val)")
    anchors.add_argument("--size", type=int, default=12000, help="at most this many captions "
                         "(a seeded sample; default 12000, 4.6 MB)")
    anchors.add_argument("--pull", type=float, default=0.5, help="the largest share of the "
                         "nearest captions' mean in a far prompt's vector (default 0.5)")
    anchors.add_argument("--agreed-pull", type=float, default=1.0, help="the same where every "
                         "neighbour's motion has the same label (action, side, angle, mode; "
                         "needs labels.jsonl; default 1.0)")
    anchors.add_argument("--seed", type=int, default=0)
    anchors.set_defaults(func=run_anchors)

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
    evaluator.set_defaults(func=run_evaluator)

    classifier = stages.add_parser("classifier", help="the action classifier of the semantic "
                                   "accuracy (procedural benchmarks: labels.jsonl)")
    _trainer_options(classifier, "classifier", batch_size=64)
    classifier.add_argument("--steps", type=int, default=1500, help="default 1500")
    classifier.set_defaults(func=run_classifier)
