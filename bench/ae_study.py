"""Which autoencoder learns fastest on this machine? Equal wall time per variant, then scores.

    python bench/ae_study.py --data synth4k --seconds 150 \\
        "transformer=ae.architecture=transformer ae.velocity_weight=0" \\
        "conv=ae.velocity_weight=0" conv_vel=

Each VARIANT is NAME=OVERRIDES (space-separated config overrides on the small preset, which is
now the conv autoencoder with the velocity term: the paper's transformer is an override). Each trains
for --seconds on one thread with the project's own stage-1 loss (train/stages.py), batch 32,
then prints the validation feature loss on the first --val test motions (smooth-L1 on normalized
features; predicting the mean scores ~0.38 on benchmark v2) and, per family, the ratio of the
reconstruction's read-out to the truth's: pelvis rise for jump and hop, the higher ankle's lift
for walk and kick (1.00 = faithful). On two cores, run two processes side by side.
The table in docs/training.md ("Equal-time study") came from it.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import torch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, required=True, help="a procedural benchmark")
    parser.add_argument("--seconds", type=float, default=150.0)
    parser.add_argument("--val", type=int, default=150)
    parser.add_argument("--batch", type=int, default=32)
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("variants", nargs="+", metavar="NAME=OVERRIDES")
    args = parser.parse_args()
    torch.set_num_threads(1)
    for variant in args.variants:
        name, _, overrides = variant.partition("=")
        print(run(args, name, overrides.split()), flush=True)


def run(args: argparse.Namespace, name: str, overrides: list[str]) -> str:
    from mlct.config import load_config
    from mlct.motion.features import recover_from_ric
    from mlct.train.stages import AutoencoderStage

    torch.manual_seed(0)
    data = args.data
    mean = torch.from_numpy(np.load(data / "Mean.npy")).float()
    std = torch.from_numpy(np.load(data / "Std.npy")).float()
    split = {s: [n.strip() for n in (data / f"{s}.txt").read_text().splitlines() if n.strip()]
             for s in ("train", "test")}
    val = split["test"][: args.val]
    features = {n: torch.from_numpy(np.load(data / "new_joint_vecs" / f"{n}.npy")[:196]).float()
                for n in split["train"] + val}
    labels = {}
    for line in (data / "labels.jsonl").read_text().splitlines():
        record = json.loads(line)
        labels[record["name"]] = record
    stage = AutoencoderStage(load_config("small", overrides), torch.device("cpu"), mean, std,
                             "humanml3d")
    model = stage.model
    optimizer = torch.optim.AdamW(model.parameters(), lr=args.lr)

    def batch(names: list[str]) -> dict[str, torch.Tensor]:
        lengths = torch.tensor([len(features[n]) for n in names])
        motion = torch.zeros(len(names), int(lengths.max()), mean.shape[0])
        for i, n in enumerate(names):
            motion[i, : lengths[i]] = (features[n] - mean) / std
        return {"motion": motion, "length": lengths}

    rng = np.random.default_rng(0)
    started, steps = time.perf_counter(), 0
    model.train()
    while time.perf_counter() - started < args.seconds:
        names = [split["train"][i] for i in rng.choice(len(split["train"]), args.batch, False)]
        loss = stage.loss(model, batch(names))["loss"]
        optimizer.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        optimizer.step()
        steps += 1

    model.eval()
    total, frames, ratios = 0.0, 0, {}
    with torch.no_grad():
        for start in range(0, len(val), 50):
            names = val[start : start + 50]
            b = batch(names)
            recon, _ = model(b["motion"], b["length"])
            for i, n in enumerate(names):
                length = int(b["length"][i])
                total += float(torch.nn.functional.smooth_l1_loss(
                    recon[i, :length], b["motion"][i, :length], reduction="sum")) / mean.shape[0]
                frames += length
                families = [a["family"] for a in labels[n]["actions"]]
                if len(families) != 1 or families[0] not in ("jump", "hop", "walk", "kick"):
                    continue
                truth = recover_from_ric(features[n])
                drawn = recover_from_ric(recon[i, :length] * std + mean)
                ratios.setdefault(families[0], []).append((_peak(truth, families[0]),
                                                           _peak(drawn, families[0])))
    scores = " ".join(f"{family} {np.mean([d for _, d in v]) / np.mean([t for t, _ in v]):.2f}"
                      for family, v in sorted(ratios.items()))
    return f"{name:12s} steps {steps:5d}  val loss {total / frames:.3f}  ratios: {scores}"


def _peak(joints: torch.Tensor, family: str) -> float:
    """Pelvis rise (jump, hop) or the higher ankle's lift (walk, kick) over the first frames."""
    watched = (0,) if family in ("jump", "hop") else (7, 8)
    return max(float(joints[:, j, 1].max() - joints[:5, j, 1].median()) for j in watched)


if __name__ == "__main__":
    main()
