#!/usr/bin/env bash
# Stage 2 of tools/make_bundled_model_3h.sh alone, on the autoencoder of an existing bundle:
#   bash tools/make_bundled_model_3h_stage2.sh MODEL_DIR WORK_DIR [CM_SEED]
# For a retraining that changes only stage 2 (captions, the denoiser's size, a seed) when the
# recipe's stage-1 runs are not at hand: tools/autoencoder_from_bundle.py writes MODEL_DIR's
# autoencoder back as the recipe's `noise` (3 body tokens) and `armdec` (6 tokens) runs, and the
# recipe's lines from "two lanes" on follow with the arm lane already done. WORK_DIR needs the
# caption sets (caption_sets in tools/recipe_stage.sh makes them if absent). The stage-2 lines
# below are the recipe's, unchanged (keep them in step). DENOISER as in the recipe (default:
# version 6's 3 x 192). The bundle of version 6 was made so, on version 5's bundle:
#   bash tools/make_bundled_model_3h_stage2.sh V5_BUNDLE WORK 0
set -euo pipefail
bundle="$1"
work="$2"
seed="${3:-0}"
source "$(dirname "$0")/recipe_stage.sh"
VERSION_6_DENOISER="denoiser.width=192 denoiser.ff_dim=768 denoiser.layers=3"
stamp data
caption_sets "${MOTIONS:-4000}"
[ -f "$work/armdec/ae/checkpoints/latest" ] ||
    python "$(dirname "$0")/autoencoder_from_bundle.py" "$bundle" "$work"
stamp stage 2 on 3 tokens
# shellcheck disable=SC2086  # DENOISER is a list of overrides, split on purpose
AE="$work/noise" DATA="$work/synth_collturns" stage cm cm --config small \
    ${DENOISER:-$VERSION_6_DENOISER} text.encoder=minilm+sides denoiser.dropout=0.0 \
    "train.cm.max_steps=${CM_STEPS:-28000}" train.cm.lr=4e-4 \
    "train.cm.seed=$seed" train.cm.precision=bf16
[ -f "$work/model_cm/config.json" ] || mlct export "$work/cm" --out "$work/model_cm"
stamp stage 2 on 6 tokens
AE="$work/armdec" DATA="$work/synth_collturns" stage cm6 cm --init "$work/model_cm" \
    text.encoder=minilm+sides denoiser.dropout=0.0 "train.cm.max_steps=${CM6_STEPS:-10000}" \
    train.cm.lr=2e-4 \
    "train.cm.seed=$((seed + 31))" train.cm.precision=bf16
if [ ! -f "$work/model/text_anchors.safetensors" ]; then
    rm -rf "$work/model"
    mlct export "$work/cm6" --out "$work/model" --half --decoder-from "$work/armdec"
    stamp durations, critic, text anchors
    mlct train durations --data "$work/synth" --model "$work/model"
    mlct train critic --data "$work/synth_rich" --model "$work/model" --samples 8
    mlct train anchors --data "$work/synth_collturns" --model "$work/model"
fi
stamp done
echo "$work/model"
