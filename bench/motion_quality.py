"""Does the model do what its text says? Physical read-outs of motions, per family and side.

    python bench/motion_quality.py --data SYNTH [--model MODEL_DIR] [--ae RUN] [--seeds 5]
        [--classifier CLS] [--limit N] [--json OUT] [--render DIR] [--candidates N]

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
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

import mlct
from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.pipeline_recon import pipeline_reconstruction
from mlct.eval.readouts import (evaluate_in_order, evaluate_label, foot_travel, heading_change,
                                pelvis_rise)
from mlct.motion.features import features_to_joints
from mlct.motion.skeleton import HUMANML3D

PROMPTS = Path(__file__).parent / "data" / "quality_prompts.json"
# paraphrases written after the everyday caption vocabulary, none of whose new verbs they use
HELDOUT = Path(__file__).parent / "data" / "quality_prompts_heldout.json"
# a second set, written 2026-11-27 before any vocabulary made after it (its "about" says how)
HELDOUT2 = Path(__file__).parent / "data" / "quality_prompts_heldout2.json"
# a third, by an author who had read no training vocabulary (its "about" says how)
HELDOUT3 = Path(__file__).parent / "data" / "quality_prompts_heldout3.json"
# a fourth, by another author, written after the text anchors were chosen on the first three
# (2026-11-28): bench/paraphrase_sets.py's check of them on prompts that did not choose them
HELDOUT4 = Path(__file__).parent / "data" / "quality_prompts_heldout4.json"
# a fifth, by a third author (2026-11-28, later), written before this session's changes were
# chosen, to check them on prompts that chose nothing
HELDOUT5 = Path(__file__).parent / "data" / "quality_prompts_heldout5.json"
# a sixth, by a fourth author who read no file of the repository, only the families and their
# label fields (2026-11-28, night): to compare the shipped model with the 3-hour recipe's
HELDOUT6 = Path(__file__).parent / "data" / "quality_prompts_heldout6.json"
# a seventh, blind as the sixth, by a fifth author (2026-11-29): written after version 5 of the
# recipe shipped, to tell the sixth set's 0.686 from a far wording the model cannot follow
HELDOUT7 = Path(__file__).parent / "data" / "quality_prompts_heldout7.json"
SIDE_KEYS = ("side", "hand", "leg")
MAX_FRAMES = 196


class Tally:
    """Pass counts per family, per named side, and overall."""

    def __init__(self) -> None:
        self.family: dict[str, list[int]] = defaultdict(lambda: [0, 0])
        self.sided: list[int] = [0, 0]
        self.motions: list[int] = [0, 0]
        # one action / a sequence / locomotion with a concurrent arm action: the autoencoder
        # keeps the first two and drops the third's arms (docs/training.md)
        self.kind: dict[str, list[int]] = defaultdict(lambda: [0, 0])

    def add(self, label: dict[str, Any], results: list[tuple[str, bool]]) -> bool:
        ok = all(passed for _, passed in results)
        self.motions[0] += ok
        self.motions[1] += 1
        kind = ("+ concurrent" if label.get("concurrent")
                else "sequence" if len(label["actions"]) > 1 else "one action")
        self.kind[kind][0] += ok
        self.kind[kind][1] += 1
        tagged = [(f"{i}:", a) for i, a in enumerate(label["actions"])]
        if label.get("concurrent"):
            tagged.append(("+:", label["concurrent"]))
        for tag, action in tagged:
            mine = [(name, p) for name, p in results if name.startswith(tag)]
            fam = self.family[action["family"]]
            fam[0] += all(p for _, p in mine)
            fam[1] += 1
            if any(k in action.get("params", {}) for k in SIDE_KEYS):
                # An action that names a side passes only if all its checks do: the named
                # side moves and the other does not (a side check alone passes a still body).
                self.sided[0] += all(p for _, p in mine)
                self.sided[1] += 1
        return ok

    @staticmethod
    def rate(pair: list[int]) -> float:
        return pair[0] / pair[1] if pair[1] else float("nan")

    def summary(self) -> dict[str, Any]:
        return {"overall": self.rate(self.motions), "motions": self.motions[1],
                "named_side": self.rate(self.sided), "named_side_n": self.sided[1],
                "kinds": {k: self.rate(v) for k, v in sorted(self.kind.items())},
                "families": {f: self.rate(v) for f, v in sorted(self.family.items())}}


def autoencoder(path: Path) -> Callable[[np.ndarray], np.ndarray]:
    """features (T, D) in real units -> the autoencoder's reconstruction (T, D); path: a
    training run, an AE checkpoint, or a model folder (its encoder and decoder)."""
    from mlct.train.stages import find_autoencoder, load_frozen_autoencoder
    if (path / "config.json").is_file():  # a model folder: the autoencoder it generates with
        from mlct.config import config_from_dict
        from mlct.generate.bundle import bundle_autoencoder_state, read_bundle
        from mlct.nn.build import build_autoencoder
        meta, tensors = read_bundle(path)
        ae = build_autoencoder(config_from_dict(meta["config"], "model config"),
                               int(meta["feature_dim"]))
        ae.load_state_dict(bundle_autoencoder_state(tensors, path))
        ae.eval().requires_grad_(False)
        mean, std = tensors["norm.mean"].float(), tensors["norm.std"].float()
    else:
        ae, norm, _ = load_frozen_autoencoder(find_autoencoder(path, None), torch.device("cpu"))
        mean, std = norm.mean, norm.std

    def run(x: np.ndarray) -> np.ndarray:
        xt = (torch.from_numpy(np.asarray(x)).float()[None] - mean) / std
        with torch.no_grad():
            recon, _ = ae(xt, torch.tensor([len(x)]), None, 0.0)
        return (recon[0] * std + mean).numpy()
    return run


def prompt_label(actions: list[dict[str, Any]], seconds: float) -> dict[str, Any]:
    """A label for a hand-written prompt: its actions share the clip in equal windows."""
    share = seconds / len(actions)
    return {"actions": [dict(a, start=i * share, end=(i + 1) * share)
                        for i, a in enumerate(actions)], "concurrent": None}


def judge_prompt(joints: np.ndarray, actions: list[dict[str, Any]], seconds: float,
                 halves: bool = False) -> tuple[dict[str, Any], list[tuple[str, bool]]]:
    """(label, check results) of a hand-written prompt's motion: one action over the whole clip;
    several in order, at the motion's own cut (or in equal windows with `halves`)."""
    label = prompt_label(actions, seconds)
    if len(actions) == 1 or halves:
        return label, evaluate_label(joints, label)
    return label, evaluate_in_order(joints, actions)


def hand_written_sets() -> dict[str, list[dict[str, Any]]]:
    """The hand-written one-action sets: the seen paraphrases and held-out sets 1 to 7."""
    def read(path: Path) -> list[dict[str, Any]]:
        return json.loads(path.read_text(encoding="utf-8"))["paraphrases"]
    return {"seen": read(PROMPTS), "held-out 1": read(HELDOUT), "held-out 2": read(HELDOUT2),
            "held-out 3": read(HELDOUT3), "held-out 4": read(HELDOUT4),
            "held-out 5": read(HELDOUT5), "held-out 6": read(HELDOUT6),
            "held-out 7": read(HELDOUT7)}


def prompt_passes(pipe: Any, items: list[dict[str, Any]], seconds: list[float],
                  seeds: int, failed: list[Counter] | None = None) -> np.ndarray:
    """How many of `seeds` samples of each hand-written prompt pass all its checks; with
    `failed` (one Counter per prompt), how often each of its checks failed."""
    count = np.zeros(len(items), dtype=int)
    for seed in range(seeds):
        made = pipe.generate([p["text"] for p in items], seconds=seconds, seed=seed * 100_000)
        for i, (item, motion) in enumerate(zip(items, made)):
            _, results = judge_prompt(motion.joints, item["actions"],
                                      motion.joints.shape[0] / pipe.skeleton.fps)
            count[i] += all(ok for _, ok in results)
            if failed is not None:
                failed[i].update(name for name, ok in results if not ok)
    return count


def in_order_judge_check(real_joints: list[np.ndarray], labels: list[dict[str, Any]]
                         ) -> dict[str, Any]:
    """The in-order judge on the data's sequences, their timing dropped: the pass rate in their
    own order (the judge must pass them) and with the actions reversed (it should fail them;
    only sequences whose reversal asks something else)."""
    own, reversed_ = [0, 0], [0, 0]
    for joints, label in zip(real_joints, labels):
        actions = [{"family": a["family"], "params": a.get("params") or {}}
                   for a in label["actions"]]
        if len(actions) < 2 or label.get("concurrent"):
            continue
        own[0] += all(p for _, p in evaluate_in_order(joints, actions))
        own[1] += 1
        if actions[::-1] != actions:
            reversed_[0] += all(p for _, p in evaluate_in_order(joints, actions[::-1]))
            reversed_[1] += 1
    return {"in_order_pass": Tally.rate(own), "sequences": own[1],
            "reversed_pass": Tally.rate(reversed_), "reversed_sequences": reversed_[1]}


def print_table(title: str, columns: dict[str, dict[str, Any]]) -> None:
    print(f"\n## {title}")
    families = sorted({f for c in columns.values() for f in c["families"]})
    print(f"{'family':<16}" + "".join(f"{name:>14}" for name in columns))
    for fam in families:
        print(f"{fam:<16}" + "".join(f"{c['families'].get(fam, float('nan')):>14.2f}"
                                      for c in columns.values()))
    print(f"{'OVERALL':<16}" + "".join(f"{c['overall']:>14.3f}" for c in columns.values()))
    print(f"{'named side':<16}" + "".join(f"{c['named_side']:>14.3f}" for c in columns.values()))
    for kind in sorted({k for c in columns.values() for k in c["kinds"]}):
        print(f"{kind:<16}" + "".join(f"{c['kinds'].get(kind, float('nan')):>14.3f}"
                                      for c in columns.values()))
    print(f"{'motions':<16}" + "".join(f"{c['motions']:>14d}" for c in columns.values()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True, help="a procedural benchmark")
    parser.add_argument("--model", type=Path, default=None, help="default: the bundled model")
    parser.add_argument("--ae", type=Path, default=None, help="run or AE checkpoint for (b)")
    parser.add_argument("--split", default="test")
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--nfe", type=int, default=5)
    parser.add_argument("--limit", type=int, default=None, help="first N motions of the split")
    parser.add_argument("--classifier", type=Path, default=None)
    parser.add_argument("--skip-generation", action="store_true", help="only (a) and (b)")
    parser.add_argument("--whole-prompt", action="store_true",
                        help="(c) and (d) give the model whole prompts: no split into actions")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--backend", default="torch", help="mlct.load's backend (torch, onnx)")
    parser.add_argument("--candidates", type=int, default=None,
                        help="best-of-N by the model's critic (default: the model's; 1 = plain)")
    args = parser.parse_args()
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
        ae = autoencoder(args.ae)
        recon, composed = Tally(), Tally()
        mpjpe, composed_mpjpe, rises, travels, turns = [], [], defaultdict(list), [], []
        for name, joints, feats in zip(names, real_joints, real):
            made = features_to_joints(ae(feats))
            recon.add(labels[name], evaluate_label(made, labels[name]))
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
        prompts = json.loads(PROMPTS.read_text(encoding="utf-8"))
        prompts["heldout"] = json.loads(HELDOUT.read_text(encoding="utf-8"))["paraphrases"]
        prompts["heldout2"] = json.loads(HELDOUT2.read_text(encoding="utf-8"))["paraphrases"]
        prompts["heldout3"] = json.loads(HELDOUT3.read_text(encoding="utf-8"))["paraphrases"]
        # "two actions" as a user gets them (each action made alone and chained,
        # generate/compose.py), and "... whole": the model given the whole prompt at once.
        for key, titles, seconds, split in (
                ("paraphrases", ("paraphrases",), 4.0, not args.whole_prompt),
                ("heldout", ("held-out para",), 4.0, not args.whole_prompt),
                ("heldout2", ("held-out 2",), 4.0, not args.whole_prompt),
                ("heldout3", ("held-out 3",), 4.0, not args.whole_prompt),
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
          f"{args.candidates or 'default'}")
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


if __name__ == "__main__":
    main()
