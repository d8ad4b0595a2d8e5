#!/usr/bin/env bash
# A bundle's decoders replaced by narrower ones trained on its frozen encoder:
#   bash tools/make_bundled_model_narrow_decoder.sh MODEL_DIR WORK_DIR [CHANNELS [ARM]]
# tools/autoencoder_from_bundle.py writes MODEL_DIR's autoencoder back as a run (`armdec`);
# `train ae --init` starts both decoders CHANNELS wide (default 96) as MODEL_DIR's own with their
# weakest channels removed (ae.decoder_init=prune, nn/narrow.py) and trains them with the
# encoder frozen, so the denoiser's latents keep their meaning; `mlct convert --decoder-from`
# then writes the bundle with them, its denoiser, critic, durations and text anchors unchanged.
# ARM: the arm pair's decoder width (default CHANNELS), or "frozen": kept as MODEL_DIR's and not
# trained (ae.freeze_arm_decoder), only the body's decoder narrowed.
# DATA=DIR trains on that benchmark instead of making one in WORK_DIR.
# Why: at batch 1 the decoder's time is its channels (docs/performance.md). The bundle's last
# step (18 min on 2 cores): DATA=SYNTH bash tools/make_bundled_model_narrow_decoder.sh \
#   src/mlct/assets/model WORK 96 frozen
set -euo pipefail
bundle="$1"
work="$2"
channels="${3:-96}"
arm="${4:-$channels}"
if [ "$arm" = frozen ]; then
    arm_options=(ae.freeze_arm_decoder=true)
else
    arm_options=(ae.arm_decoder_channels="$arm")
fi
source "$(dirname "$0")/recipe_stage.sh"
stamp data
[ -n "${DATA:-}" ] || caption_sets "${MOTIONS:-4000}"  # DATA=DIR: a benchmark made before
[ -f "$work/armdec/ae/checkpoints/latest" ] ||  # resumable: each step skipped once done
    python "$(dirname "$0")/autoencoder_from_bundle.py" "$bundle" "$work"
stamp "decoders at $channels channels, arms $arm"
OMP_NUM_THREADS="${THREADS:-2}" stage "narrow${channels}_$arm" ae --init "$work/armdec" \
    ae.freeze_encoder=true ae.decoder_channels="$channels" "${arm_options[@]}" \
    train.ae.max_steps=8000 train.ae.lr=5e-4 train.ae.precision=bf16 train.ae.weight_decay=0
[ -f "$work/model/config.json" ] ||
    mlct convert "$bundle" --decoder-from "$work/narrow${channels}_$arm" --out "$work/model"
stamp done
echo "$work/model"
