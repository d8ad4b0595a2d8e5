"""What a text-to-latent stage could reach with this text encoder and this autoencoder.

    python bench/stage2_references.py --data SYNTH --ae RUN [--steps 3000] [--limit N]

Two references for the read-out pass rate of stage 2 (bench/motion_quality.py's test-caption
column), each on the test split's first captions:
  retrieval   the training motion whose caption's pooled MiniLM vector is nearest to the test
              caption's, its ground-truth joints scored against the test label: what the text
              vector alone tells apart, with no decoder loss and no averaging;
  regression  an MLP from the pooled vector to the AE latent, trained by mean squared error on
              the training motions' latents, decoded: the conditional mean of the latent
              (--scales also decodes mean + s (prediction - mean), which is what guidance
              weights do to a mean). A sampler that only finds the conditional mean gets this.
A stage 2 below the regression has not yet learned what the text says; one between the two is
sampling but blurring; only one above the retrieval composes better than look-up.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from mlct.data.layout import DatasetLayout
from mlct.eval.judge.action_classifier import read_labels
from mlct.eval.readouts import evaluate_label
from mlct.motion.features import features_to_joints
from mlct.text import load_text_encoder
from mlct.train.stages import find_autoencoder, load_frozen_autoencoder

MAX_FRAMES = 196


def passes(joints: np.ndarray, label: dict) -> bool:
    return all(ok for _, ok in evaluate_label(joints, label))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, required=True)
    parser.add_argument("--ae", type=Path, required=True, help="run or AE checkpoint")
    parser.add_argument("--steps", type=int, default=3000, help="regression MLP steps")
    parser.add_argument("--scales", default="1,2,3")
    parser.add_argument("--limit", type=int, default=None)
    args = parser.parse_args()
    torch.manual_seed(0)
    layout, labels = DatasetLayout.existing(args.data), read_labels(args.data)
    train = [n for n in layout.read_split("train") if n in labels]
    test = [n for n in layout.read_split("test") if n in labels][: args.limit]
    encoder = load_text_encoder("minilm")
    train_caps = [(i, r.caption) for i, n in enumerate(train) for r in layout.read_texts(n)]
    keys = encoder.encode([c for _, c in train_caps])  # (C, 384), unit norm
    owner = torch.tensor([i for i, _ in train_caps])
    queries = encoder.encode([layout.read_texts(n)[0].caption for n in test])
    start = time.perf_counter()

    nearest = (queries @ keys.T).argmax(1)
    retrieval = np.mean([
        passes(features_to_joints(layout.load_features(train[int(owner[j])])[:MAX_FRAMES]),
               labels[name]) for name, j in zip(test, nearest)])

    ae, norm, _ = load_frozen_autoencoder(find_autoencoder(args.ae, None), torch.device("cpu"))

    def features(name: str) -> torch.Tensor:
        x = torch.from_numpy(layout.load_features(name)[:MAX_FRAMES]).float()
        return ((x - norm.mean) / norm.std)[None]  # (1, T, D)

    with torch.no_grad():
        latents = torch.cat([ae.encode(x, torch.tensor([x.shape[1]])).z
                             for x in map(features, train)])  # (N, n, d)
    mlp = nn.Sequential(nn.Linear(keys.shape[1], 1024), nn.GELU(), nn.Linear(1024, 1024),
                        nn.GELU(), nn.Linear(1024, latents[0].numel()))
    optimizer = torch.optim.AdamW(mlp.parameters(), lr=1e-3)
    for _ in range(args.steps):
        batch = torch.randint(0, len(train_caps), (128,))
        loss = (mlp(keys[batch]) - latents[owner[batch]].flatten(1)).square().mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
    with torch.no_grad():
        predicted = mlp(queries).view(-1, *latents.shape[1:])
    mean = latents.mean(0)
    print(f"{len(test)} test captions of {args.data}; autoencoder {args.ae}")
    print(f"retrieval (nearest caption, ground-truth joints): pass {retrieval:.3f}")
    test_frames = [min(len(layout.load_features(name)), MAX_FRAMES) for name in test]
    for scale in (float(s) for s in args.scales.split(",")):
        z = (mean + scale * (predicted - mean)).clamp(-1, 1)
        rate = []
        for i, (name, frames) in enumerate(zip(test, test_frames)):
            with torch.no_grad():
                made = norm.denormalize(ae.decode(z[i : i + 1], torch.tensor([frames])))[0]
            rate.append(passes(features_to_joints(made.numpy()), labels[name]))
        print(f"regression (conditional mean, scale {scale:g}, final train MSE {loss.item():.3f}):"
              f" pass {np.mean(rate):.3f}")
    print(f"{time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
