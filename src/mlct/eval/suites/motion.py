"""The benchmark suite: does the model do what its text says? Read-outs per family and side.

    python bench/quality.py motion --data SYNTH [--model MODEL_DIR] [--ae RUN] [--seeds 5]
        [--classifier CLS] [--limit N] [--json OUT] [--candidates N] [--critic-margin M]
        [--skip-generation] [--reading-gaps]

Every motion is scored by mlct.eval.readouts: the checks that a benchmark label (family, side,
count, direction) implies, read from the joints alone. It prints the pass rate, per family and
overall, of
  (a) the ground-truth test motions (must be >= 98%, or the read-outs are wrong);
  (b) the autoencoder's reconstructions of them (--ae RUN: a training run, its AE checkpoint,
      or a model folder), with MPJPE and the pelvis-rise (jumps, hops), foot-travel (walks) and
      heading (turns) ratios to the truth; "AE recon" gives the autoencoder each clip whole,
      "as pipeline" composes the clip as generate() composes a motion (each action of a
      sequence alone, then chained; a concurrent arm action alone, standing, its arms then
      re-attached: mlct/eval/pipeline_recon.py), the best the pipeline's stage 2 could reach;
      --reading-gaps adds, for each family whose reconstructions pass less often than its
      truth, the read-outs that moved most (suites/reading_gaps.py);
  (c) generations from the test captions at the real lengths, --nfe, --seeds seeds;
  (d) generations from hand-written paraphrases (bench/data/quality_prompts.json), and from
      held-out ones (quality_prompts_heldout.json: written after the everyday caption
      vocabulary that `mlct data rephrase` trains on, using none of its new verbs; "held-out
      2", quality_prompts_heldout2.json: 43 more, two per family (three turns), written after
      the first set had been used to choose pipeline rules, so a fresh measure; "held-out 3",
      quality_prompts_heldout3.json: 48 more by an author who had read no training vocabulary,
      written before the colloquial vocabulary was trained on);
  (e) generations from two-action prompts, as the pipeline makes them (one part per action,
      chained) and as one whole prompt. A hand-written prompt has no labelled timing, so its
      actions are judged in order at the cut that suits the motion best (each part >= 1 s:
      readouts.evaluate_in_order); "two, halves" is the stricter judge of first action in the
      first half, second in the second. The in-order judge is checked on the data's own
      sequences (timing dropped): it must pass them, and fail them with their actions reversed;
and, for the actions that name a side or turn direction, how often all their checks pass (the
named side moves, the other does not).
(b) next to (c) says where quality is lost: stage 1 or stage 2. --classifier adds the action
classifier's exact-set accuracy and mean recall on (c). The default model is the bundled one.
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import torch

import mlct
from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.pipeline_recon import pipeline_reconstruction
from mlct.eval.readouts import evaluate_label, foot_travel, heading_change, pelvis_rise
from mlct.eval.suites.common import (MAX_FRAMES, Tally, in_order_judge_check, judge_prompt,
                                     print_table, prompt_file, set_critic_margin)
from mlct.eval.suites.reading_gaps import ReadingGaps
from mlct.motion.features import features_to_joints
from mlct.motion.skeleton import HUMANML3D


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--data", type=Path, required=True, help="a procedural benchmark")
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--ae", type=Path, default=None, help="run or AE checkpoint for (b)")
    parser.add_argument("--split", default="test")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--nfe", type=int, default=5)
    parser.add_argument("--limit", type=int, default=None, help="first N motions of the split")
    parser.add_argument("--classifier", type=Path, default=None)
    parser.add_argument("--skip-generation", action="store_true", help="only (a) and (b)")
    parser.add_argument("--reading-gaps", action="store_true",
                        help="with --ae: the read-outs each failing family's reconstructions lose")
    parser.add_argument("--whole-prompt", action="store_true",
                        help="(c) and (d) give the model whole prompts: no split into actions")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--backend", default="torch", help="mlct.load's backend (torch, onnx)")
    parser.add_argument("--candidates", type=int, default=None,
                        help="best-of-N by the model's critic (default: the model's; 1 = plain)")
    parser.add_argument("--critic-margin", type=float, default=None,
                        help="the first candidate this close to the critic's best (default: the "
                             "model's; 0 = the best)")


def run(args: argparse.Namespace) -> None:
    torch.manual_seed(0)

    layout = DatasetLayout.existing(args.data)
    labels = read_labels(args.data)
    names = [n for n in layout.read_split(args.split) if n in labels][: args.limit]
    # The models' horizon is 196 frames (HumanML3D's); the few longer clips lose their last frames.
    real = [layout.load_features(n)[:MAX_FRAMES] for n in names]
    real_joints = [features_to_joints(f) for f in real]
    report: dict[str, Any] = {"data": str(args.data), "split": args.split, "motions": len(names)}

    truth = Tally()
    for name, joints in zip(names, real_joints):
        truth.add(labels[name], evaluate_label(joints, labels[name]))
    columns = {"ground truth": truth.summary()}
    report["in_order_judge"] = in_order_judge_check(real_joints, [labels[n] for n in names])

    if args.ae is not None:
        ae = args.load_autoencoder(args.ae)
        recon, composed, gaps = Tally(), Tally(), ReadingGaps()
        mpjpe, composed_mpjpe, rises, travels, turns = [], [], defaultdict(list), [], []
        for name, joints, feats in zip(names, real_joints, real):
            made = features_to_joints(ae(feats))
            recon.add(labels[name], evaluate_label(made, labels[name]))
            if args.reading_gaps:
                gaps.add(labels[name], joints, made)
            mpjpe.append(float(np.linalg.norm(made - joints, axis=-1).mean()))
            # (b'): stage 1 as the pipeline uses it (mlct/eval/pipeline_recon.py)
            whole = pipeline_reconstruction(feats, labels[name],
                                            lambda f: features_to_joints(ae(f)), HUMANML3D,
                                            joints)
            composed.add(labels[name], evaluate_label(whole, labels[name]))
            composed_mpjpe.append(float(np.linalg.norm(whole - joints, axis=-1).mean()))
            families = [a["family"] for a in labels[name]["actions"]]
            if len(families) == 1 and families[0] in ("jump", "hop"):
                rises[families[0]].append((pelvis_rise(joints), pelvis_rise(made)))
            if len(families) == 1 and families[0] == "walk":
                travels.append((sum(foot_travel(joints).values()), sum(foot_travel(made).values())))
            if len(families) == 1 and families[0] == "turn":
                turns.append((abs(heading_change(joints)), abs(heading_change(made))))
        columns["AE recon"] = recon.summary()
        columns["as pipeline"] = composed.summary()
        if args.reading_gaps:
            truth_rates, recon_rates = truth.summary()["families"], recon.summary()["families"]
            gaps.print_for([f for f, rate in sorted(recon_rates.items())
                            if rate < truth_rates.get(f, 0.0)])
        ratios = {f"pelvis_rise_{f}": float(np.mean([m for _, m in v]) / np.mean([t for t, _ in v]))
                  for f, v in rises.items()}
        if travels:
            ratios["foot_travel_walk"] = float(np.mean([m for _, m in travels])
                                               / np.mean([t for t, _ in travels]))
        if turns:
            ratios["heading_turn"] = float(np.mean([m for _, m in turns])
                                           / np.mean([t for t, _ in turns]))
        report["reconstruction"] = {"mpjpe_m": float(np.mean(mpjpe)),
                                    "mpjpe_as_pipeline_m": float(np.mean(composed_mpjpe)),
                                    **ratios}

    if not args.skip_generation:
        pipe = mlct.load(args.model, backend=args.backend)
        set_critic_margin(pipe, args.critic_margin)
        captions = [layout.read_texts(n)[0].caption for n in names]
        lengths = [min(len(r), pipe.max_frames) for r in real]
        generated, made_features, targets = Tally(), [], []
        start = time.perf_counter()
        for seed in range(args.seeds):
            out = pipe.generate(captions, lengths=lengths, nfe=args.nfe, seed=seed * 100_000,
                                split_actions=not args.whole_prompt,
                                candidates=args.candidates)
            for name, motion in zip(names, out):
                generated.add(labels[name], evaluate_label(motion.joints, labels[name]))
                made_features.append(motion.features)
                targets.append(labels[name])
        columns["captions"] = generated.summary()
        prompts = prompt_file(args.prompt_dir, "seen")
        for key in ("held-out 1", "held-out 2", "held-out 3"):
            prompts[key] = prompt_file(args.prompt_dir, key)["paraphrases"]
        # "two actions" as a user gets them (each action made alone and chained,
        # generate/compose/actions.py), and "... whole": the model given the whole prompt at once.
        for key, titles, seconds, split in (
                ("paraphrases", ("paraphrases",), 4.0, not args.whole_prompt),
                ("held-out 1", ("held-out para",), 4.0, not args.whole_prompt),
                ("held-out 2", ("held-out 2",), 4.0, not args.whole_prompt),
                ("held-out 3", ("held-out 3",), 4.0, not args.whole_prompt),
                ("two_actions", ("two actions", "two, halves"), 7.0, True),
                ("two_actions", ("two, whole",), 7.0, False)):
            tallies = [Tally() for _ in titles]
            items = prompts[key]
            for seed in range(args.seeds):
                out = pipe.generate([p["text"] for p in items], seconds=seconds, nfe=args.nfe,
                                    seed=seed * 100_000, split_actions=split,
                                    candidates=args.candidates)
                for item, motion in zip(items, out):
                    for tally, title in zip(tallies, titles):
                        tally.add(*judge_prompt(motion.joints, item["actions"],
                                                motion.joints.shape[0] / pipe.skeleton.fps,
                                                halves=title.endswith("halves")))
            for tally, title in zip(tallies, titles):
                columns[title] = tally.summary()
        report["generation_seconds"] = time.perf_counter() - start
        if args.classifier is not None:
            from mlct.eval.judge.action_classifier import (action_targets, load_action_classifier,
                                                           semantic_accuracy)
            classifier = load_action_classifier(args.classifier)
            sem = semantic_accuracy(classifier, made_features, [action_targets(t) for t in targets])
            report["classifier"] = {"exact_set_accuracy": sem["exact_set_accuracy"],
                                    "mean_recall": sem["mean_recall"]}

    print(f"{len(names)} motions of {args.data} ({args.split}); nfe {args.nfe}, "
          f"{args.seeds} seeds; model {args.model or 'bundled'}; candidates "
          f"{args.candidates or 'default'}; critic margin "
          f"{'default' if args.critic_margin is None else args.critic_margin}")
    print_table("read-out pass rates", columns)
    judge = report["in_order_judge"]
    print(f"\nin-order judge on the data's {judge['sequences']} sequences (timing dropped): passes "
          f"{judge['in_order_pass']:.3f}; the same actions reversed ({judge['reversed_sequences']}"
          f"): passes {judge['reversed_pass']:.3f}")
    for key in ("reconstruction", "classifier"):
        if key in report:
            print(f"\n{key}: " + ", ".join(f"{k} {v:.3f}" for k, v in report[key].items()))
    report["columns"] = columns
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
