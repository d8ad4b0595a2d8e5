"""Write a bundle's autoencoder back as stage-1 checkpoints, so that stage 2 can be retrained
on the bundle's own latents when the recipe's stage-1 runs are gone:

    python tools/autoencoder_from_bundle.py MODEL_DIR OUT

OUT/armdec: the whole 6-token autoencoder (body and arm pair) as the recipe's last stage-1 run
left it, the `AE` of the 6-token stage 2 and the `--decoder-from` of the export.
OUT/noise: the body's 3 tokens alone, the `AE` of the 3-token stage 2. The arm pair was trained
with the body's encoder frozen (ae.freeze_encoder), so the bundle's body encoder is the one the
recipe's 3-token stage 2 read, up to float16 storage. Its decoder is the bundle's body decoder,
whose output layer writes the body's columns only; the arm columns' rows start at zero. Stage 2
never decodes (consistency.motion_weight is 0), so no trained weight depends on them.
"""
from __future__ import annotations

import copy
import sys
from pathlib import Path

import torch

from mlct.config import config_from_dict
from mlct.generate.bundle import bundle_autoencoder_state, read_bundle
from mlct.motion.features import arm_feature_columns
from mlct.nn.build import build_autoencoder
from mlct.train.checkpoint import save_checkpoint

STEP = 0  # no step of training happened here; the checkpoint only carries the weights


def write(out: Path, config: dict, meta: dict, ae_state: dict, tensors: dict) -> None:
    weights = {**{f"ae.{k}": v.float().contiguous() for k, v in ae_state.items()},
               "norm.mean": tensors["norm.mean"].float(), "norm.std": tensors["norm.std"].float()}
    checkpoint_meta = {"stage": "ae", "config": config, "feature_dim": meta["feature_dim"],
                       "skeleton": meta["skeleton"]}
    save_checkpoint(out / "ae" / "checkpoints", STEP, weights, checkpoint_meta, state={})
    print(out)


def main(model_dir: str, out: str) -> None:
    meta, tensors = read_bundle(model_dir)
    whole = bundle_autoencoder_state(tensors, model_dir)
    config = copy.deepcopy(meta["config"])
    write(Path(out) / "armdec", config, meta, whole, tensors)

    body = copy.deepcopy(config)
    # the recipe's `noise` stage: 3 tokens, no arm pair, its latent noise (make_bundled_model_3h.sh)
    body["ae"].update(n_tokens=3, arm_tokens=0, freeze_encoder=False, latent_noise=0.1,
                      grown_from=0)
    model = build_autoencoder(config_from_dict(body, "body"), meta["feature_dim"])
    state = model.state_dict()
    # the body decoder's output rows: every feature but the arm pair's (as the 6-token model)
    arms = set(arm_feature_columns(meta["feature_dim"]))
    rows = [f for f in range(meta["feature_dim"]) if f not in arms]
    for key, value in state.items():
        source = whole[key]
        if source.shape == value.shape:
            state[key] = source.float()
        else:  # the output layer: the 6-token body decoder writes the body's columns only
            filled = torch.zeros_like(value)
            filled[rows] = source.float()
            state[key] = filled
            print(f"{key}: {source.shape[0]} body rows copied, the other "
                  f"{value.shape[0] - source.shape[0]} zero", file=sys.stderr)
    write(Path(out) / "noise", body, meta, state, tensors)


if __name__ == "__main__":
    main(*sys.argv[1:3])
