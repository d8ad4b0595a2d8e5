"""What the quality suites share: the read-outs' tally, the judge of a hand-written prompt's
motion, and the hand-written prompt sets (their files live in bench/data).

A motion is judged by mlct.eval.readouts: the checks a benchmark label (family, side, count,
direction) implies, read from the joints alone. A hand-written prompt has no labelled timing,
so one action is judged over the whole clip and several in order at the motion's own cut
(readouts.evaluate_in_order).
"""

from __future__ import annotations

import json
from collections import Counter, defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from mlct.eval.readouts import evaluate_in_order, evaluate_label

# the hand-written one-action sets, by name: "seen" (the paraphrases the vocabularies were
# written after), then held-out sets, each written without the training vocabularies (see each
# file's "about"); sets 6 and 7 by authors who read no file of the repository
PROMPT_FILES = {"seen": "quality_prompts.json", "held-out 1": "quality_prompts_heldout.json",
                **{f"held-out {k}": f"quality_prompts_heldout{k}.json" for k in range(2, 8)}}
SIDE_KEYS = ("side", "hand", "leg")
MAX_FRAMES = 196  # the models' horizon (HumanML3D's); the few longer clips lose their last frames


class Tally:
    """Pass counts per family, per named side, and overall."""

    def __init__(self) -> None:
        self.family: dict[str, list[int]] = defaultdict(lambda: [0, 0])
        self.sided: list[int] = [0, 0]
        self.motions: list[int] = [0, 0]
        # one action / a sequence / locomotion with a concurrent arm action
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


def set_critic_margin(pipe: Any, margin: float | None) -> None:
    """A suite's --critic-margin on a loaded model (None: the model's own)."""
    if margin is not None:
        from mlct.generate.compose.critic import set_margin

        set_margin(pipe, margin)


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


def prompt_file(prompt_dir: Path, name: str) -> dict[str, Any]:
    """One of the prompt files of `prompt_dir` (bench/data), by its name in PROMPT_FILES."""
    return json.loads((Path(prompt_dir) / PROMPT_FILES[name]).read_text(encoding="utf-8"))


def hand_written_sets(prompt_dir: Path) -> dict[str, list[dict[str, Any]]]:
    """The hand-written one-action sets: the seen paraphrases and held-out sets 1 to 7."""
    return {name: prompt_file(prompt_dir, name)["paraphrases"] for name in PROMPT_FILES}


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
