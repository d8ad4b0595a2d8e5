#!/usr/bin/env bash
# A candidate one-pass recipe for the bundled model, aimed at issue 14's 3 hours on 2 cores:
#   bash tools/make_bundled_model_3h.sh [WORK_DIR] [CM_SEED]
# tools/make_bundled_model.sh grew stage by stage as each change was found (about 7 h 45 min,
# 107,000 stage-2 steps on four autoencoders). This recipe applies what those stages found
# from the start, once each, and trains in bfloat16 autocast (the CPU has avx512_bf16: 1.5x
# the samples/s of float32 for both stages, same validation losses after 400-500 steps;
# docs/training.md, "A 3-hour recipe"):
# - the autoencoder in two parts: 10,000 plain steps, then 5,000 with the latent noise, the
#   hold past an action's end and the root's integrated path in its loss (trained with all of
#   them from step 0 it drew no clap, wave or punch: reconstructions 0.582, claps 0.14);
# - stage 2 once, with the side-contrasted text ('minilm+sides') and on the captioned-richly,
#   oversampled data (everyday captions, single claps, waves and turns listed 3x) from step 0,
#   one cosine schedule (30,000 steps, lr 4e-4);
# - the decoder alone with twice the latent noise (3,000 steps, encoder frozen), then the
#   duration model and the best-of-N critic.
# Resumable: run it again with the same WORK_DIR and each stage continues from its last
# checkpoint. Unlike make_bundled_model.sh it does not replace src/mlct/assets/model: it writes
# WORK_DIR/model, to be measured against the bundle first.
set -euo pipefail
work="${1:-mlct-bundled-3h}"
seed="${2:-0}"
source "$(dirname "$0")/recipe_stage.sh"
stamp data
[ -f "$work/synth/synth.json" ] || mlct data synth --out "$work/synth" --num 4000 --seed 0 --workers 2
[ -f "$work/synth_rich/synth.json" ] || mlct data rephrase "$work/synth" --out "$work/synth_rich"
[ -f "$work/synth_focus/synth.json" ] || mlct data oversample "$work/synth_rich" \
    --out "$work/synth_focus" --families clap,wave,turn --times 3
stamp autoencoder
stage run ae --config small train.ae.precision=bf16
stamp autoencoder, noisy latent
stage noise ae --init "$work/run" ae.latent_noise=0.1 ae.hold_extension=0.5 \
    ae.trajectory_weight=1.0 train.ae.max_steps=5000 train.ae.lr=3e-4 train.ae.precision=bf16
stamp stage 2
DATA="$work/synth_focus" AE="$work/noise" stage cm cm --config small \
    text.encoder=minilm+sides train.cm.max_steps=30000 train.cm.lr=4e-4 "train.cm.seed=$seed" \
    train.cm.precision=bf16
[ -f "$work/model_cm/config.json" ] || mlct export "$work/cm" --out "$work/model_cm" --half
stamp decoder
# the decoder alone, twice the latent noise (docs/training.md, "Damped later cycles"); the
# encoder is frozen, so stage 2's latents keep their meaning
stage dnoise ae --init "$work/model_cm" ae.freeze_encoder=true ae.trajectory_weight=1.0 \
    ae.latent_noise=0.2 ae.hold_extension=0.5 train.ae.max_steps=3000 train.ae.lr=1e-4 \
    train.ae.precision=bf16
if [ ! -f "$work/model/critic.safetensors" ]; then
    rm -rf "$work/model"
    mlct export "$work/cm" --out "$work/model" --half --decoder-from "$work/dnoise"
    stamp durations and critic
    mlct train durations --data "$work/synth" --model "$work/model"
    mlct train critic --data "$work/synth_rich" --model "$work/model" --samples 8
fi
stamp done
echo "$work/model"
